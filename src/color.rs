//! Colour encoding: linear light to 8-bit sRGB, exactly as the sRGB
//! formula gives it, without a `powf` per channel.

/// sRGB encoding without a powf per channel: for each byte, the least
/// linear value that encodes to it, found from [`encode_srgb`] itself, so
/// the table gives exactly the same bytes.
pub struct SrgbTable {
    /// `thresholds[b]`: least f32 (as bits; positive floats order like
    /// their bits) that encodes to byte b or more; `thresholds[256]` is
    /// out of reach.
    thresholds: [u32; 257],
    /// For each bucket of the f32 bit pattern, the byte at its low end.
    buckets: Vec<u8>,
    /// As `thresholds` and `buckets`, for quarter codes (see
    /// [`SrgbTable::encode_quarters`]).
    quarter_thresholds: Vec<u32>,
    quarter_buckets: Vec<u16>,
    /// Per quarter code, the linear value at the middle of its span.
    quarter_linear: Vec<f32>,
}

/// Quarter codes: an sRGB byte in steps of a quarter (0..1024).
pub const QUARTER_CODES: u32 = 1024;

/// Bits of the f32 pattern that select a bucket; at the steepest part of
/// the curve a bucket then spans far less than one byte step.
const SRGB_BUCKET_SHIFT: u32 = 13;

/// For each bucket of the f32 bit patterns of [0, 1], the step (byte or
/// quarter code) its low end falls in, given each step's least pattern.
fn bucket_starts(thresholds: &[u32]) -> impl Iterator<Item = usize> + '_ {
    let count = (1.0f32.to_bits() >> SRGB_BUCKET_SHIFT) + 1;
    (0..count).map(move |bucket| {
        let low = bucket << SRGB_BUCKET_SHIFT;
        thresholds.partition_point(|&t| t <= low) - 1
    })
}

impl SrgbTable {
    fn new() -> SrgbTable {
        let mut thresholds = [u32::MAX; 257];
        thresholds[0] = 0;
        for (byte, threshold) in thresholds.iter_mut().enumerate().take(256).skip(1) {
            // Bisect on the bit pattern of [0, 1].
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if usize::from(encode_srgb(f32::from_bits(mid))) >= byte {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *threshold = lo;
        }
        let buckets = bucket_starts(&thresholds).map(|b| b as u8).collect();
        // A byte's span of linear values, thresholds[b]..thresholds[b + 1],
        // cut in four equal parts; 255's reaches past 1.0, where encoding
        // stops, as far again as from its threshold (1.0 is then at its
        // middle, as 255 * s + 0.5 = 255.5 puts it).
        let mut quarter_thresholds = vec![u32::MAX; QUARTER_CODES as usize + 1];
        for (byte, &low) in thresholds.iter().enumerate().take(256) {
            let lo = f32::from_bits(low);
            let hi = match thresholds[byte + 1] {
                u32::MAX => 2.0 - lo,
                high => f32::from_bits(high),
            };
            for quarter in 0..4 {
                quarter_thresholds[4 * byte + quarter] =
                    (lo + quarter as f32 * 0.25 * (hi - lo)).to_bits();
            }
        }
        let quarter_buckets = bucket_starts(&quarter_thresholds)
            .map(|code| code as u16)
            .collect();
        let quarter_linear = quarter_thresholds
            .windows(2)
            .map(|span| {
                let lo = f32::from_bits(span[0]);
                let hi = f32::from_bits(span[1]).min(1.0);
                (lo + 0.5 * (hi - lo)).min(1.0)
            })
            .collect();
        SrgbTable {
            thresholds,
            buckets,
            quarter_thresholds,
            quarter_buckets,
            quarter_linear,
        }
    }

    /// A linear value as an sRGB byte in quarter steps: `4 * encode(linear)`
    /// plus the quarter of that byte's span of linear values the value lies
    /// in (the curve is nearly straight across one byte). `code >> 2` is
    /// exactly `encode(linear)`: blending the codes of equal values gives
    /// their byte back, and the extra bits keep a blend of different ones
    /// within an eighth of a byte step instead of half of one.
    pub fn encode_quarters(&self, linear: f32) -> u32 {
        let c = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
        let bits = c.to_bits();
        // As in `encode`: a bucket spans less than one quarter (tested).
        let code = u32::from(self.quarter_buckets[(bits >> SRGB_BUCKET_SHIFT) as usize]);
        code + u32::from(bits >= self.quarter_thresholds[code as usize + 1])
    }

    /// The linear value a quarter code stands for: the middle of its span.
    pub fn decode_quarters(&self, code: u32) -> f32 {
        self.quarter_linear[code as usize]
    }

    pub fn encode(&self, linear: f32) -> u8 {
        // NaN and negatives to 0, above 1 to 255.
        let c = if linear > 0.0 { linear.min(1.0) } else { 0.0 };
        let bits = c.to_bits();
        // A bucket spans less than one byte step (tested), so one compare
        // settles it, without a loop in the per-pixel path.
        let byte = self.buckets[(bits >> SRGB_BUCKET_SHIFT) as usize];
        byte + u8::from(bits >= self.thresholds[usize::from(byte) + 1])
    }
}

/// The shared table, built on first use.
pub fn srgb_table() -> &'static SrgbTable {
    static TABLE: std::sync::OnceLock<SrgbTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(SrgbTable::new)
}

/// Linear [0, 1] to an sRGB byte.
pub fn encode_srgb(linear: f32) -> u8 {
    let c = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each bucket's step at its low end (`starts`) against the step of
    /// its last bit pattern (`step_of`): one compare settles a lookup only
    /// if they are at most one step apart.
    fn assert_buckets_span_one_step(
        starts: impl Iterator<Item = usize>,
        step_of: impl Fn(u32) -> usize,
    ) {
        for (bucket, first) in starts.enumerate() {
            let high = (((bucket as u32 + 1) << SRGB_BUCKET_SHIFT) - 1).min(1.0f32.to_bits());
            let last = step_of(high);
            assert!(last <= first + 1, "bucket {bucket}: {first}..{last}");
        }
    }

    #[test]
    fn srgb_buckets_span_at_most_one_byte_step() {
        let table = srgb_table();
        assert_buckets_span_one_step(table.buckets.iter().map(|&b| usize::from(b)), |bits| {
            usize::from(encode_srgb(f32::from_bits(bits)))
        });
    }

    #[test]
    fn srgb_table_matches_the_formula_everywhere() {
        let table = srgb_table();
        // Every 97th bit pattern in [0, 1] plus values around each threshold.
        let mut values: Vec<f32> = (0..=1.0f32.to_bits())
            .step_by(97)
            .map(f32::from_bits)
            .collect();
        for &t in &table.thresholds[..256] {
            values.extend([
                f32::from_bits(t.saturating_sub(1)),
                f32::from_bits(t),
                f32::from_bits(t + 1),
            ]);
        }
        values.extend([-1.0, 2.0, f32::NAN, f32::INFINITY, -0.0]);
        for v in values {
            assert_eq!(table.encode(v), encode_srgb(v), "{v}");
        }
    }

    #[test]
    fn srgb_buckets_span_at_most_one_quarter_step() {
        let table = srgb_table();
        // A pattern's code by search of the quarter thresholds.
        let thresholds = &table.quarter_thresholds;
        assert_buckets_span_one_step(
            table.quarter_buckets.iter().map(|&c| usize::from(c)),
            |bits| thresholds.partition_point(|&t| t <= bits) - 1,
        );
    }

    #[test]
    fn quarter_codes_refine_the_byte_and_round_trip() {
        let table = srgb_table();
        let mut values: Vec<f32> = (0..=1.0f32.to_bits())
            .step_by(997)
            .map(f32::from_bits)
            .collect();
        for &t in &table.thresholds[..256] {
            values.extend([f32::from_bits(t.saturating_sub(1)), f32::from_bits(t)]);
        }
        values.extend([-1.0, 2.0, f32::NAN, f32::INFINITY, -0.0, 1.0]);
        values.sort_by(f32::total_cmp);
        let mut last = 0;
        for v in values {
            let code = table.encode_quarters(v);
            assert_eq!(code >> 2, u32::from(table.encode(v)), "{v}");
            if !v.is_nan() && v >= 0.0 {
                assert!(code >= last, "{v}: {code} after {last}");
                last = code;
            }
        }
        // Every code is reached, and its middle encodes back to it; but
        // the last, past 1.0, which no value or blend of values reaches.
        for code in 0..QUARTER_CODES - 1 {
            let middle = table.decode_quarters(code);
            assert_eq!(table.encode_quarters(middle), code, "{code}: {middle}");
        }
        assert_eq!(table.encode_quarters(1.0), 4 * 255 + 2);
    }

    #[test]
    fn srgb_encoding_endpoints() {
        assert_eq!(encode_srgb(0.0), 0);
        assert_eq!(encode_srgb(1.0), 255);
        assert_eq!(encode_srgb(2.0), 255);
        assert_eq!(encode_srgb(f32::NAN), 0);
        assert_eq!(encode_srgb(-1.0), 0);
        assert!(encode_srgb(0.5) > 180);
    }
}
