//! Transparent materials (Whitted refraction) as scene files and MTL
//! libraries describe them.
//!
//! Promises: a [`Glass`] has a transparency within (0, 1], an index of
//! refraction above 0 and a finite, non-negative filter colour. An opaque
//! material has none, so scenes without glass carry nothing for it.
//!
//! From MTL: the transparency is `1 - d` (dissolve), else `Tr`; the filter
//! `Tf`; the index `Ni`, but only under the illumination models that
//! refract (`illum 4`, `6`, `7`): elsewhere a dissolved material is seen
//! through without bending (index 1), as MTL's dissolve is.

use glam::Vec3;

/// How a transparent material lets light through.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glass {
    /// Share of the surface's colour that is what lies behind it (Fresnel
    /// reflection included), the rest being its own shading: 0..1.
    pub transparency: f32,
    /// Index of refraction of the inside, relative to the outside (the
    /// side the surface's normal points to).
    pub ior: f32,
    /// Colour that light crossing into the material is multiplied by.
    pub filter: Vec3,
}

/// The index of refraction of a transparent material that names none in
/// a scene file: common glass.
pub const DEFAULT_IOR: f32 = 1.5;

impl Glass {
    /// The glass of these values, `None` for a transparency of 0; on a
    /// value out of range, the field at fault (`transparency`, `ior`,
    /// `transmission_filter`) and why.
    pub fn new(
        transparency: f32,
        ior: f32,
        filter: Vec3,
    ) -> Result<Option<Glass>, (&'static str, String)> {
        if !(0.0..=1.0).contains(&transparency) {
            return Err((
                "transparency",
                format!("must be within 0..1, got {transparency}"),
            ));
        }
        if !(ior.is_finite() && ior > 0.0) {
            return Err((
                "ior",
                format!("an index of refraction must be above 0, got {ior}"),
            ));
        }
        if !(filter.is_finite() && filter.cmpge(Vec3::ZERO).all()) {
            return Err((
                "transmission_filter",
                format!("must be finite and not negative, got {filter}"),
            ));
        }
        Ok((transparency > 0.0).then_some(Glass {
            transparency,
            ior,
            filter,
        }))
    }
}

/// What is wrong with an MTL line's glass value (`d`, `Tr`, `Ni`, `Tf`),
/// once its numbers parse: `None` when nothing is.
pub(super) fn mtl_value_problem(keyword: &str, values: &[&str]) -> Option<String> {
    let first: f32 = values.first()?.parse().ok()?;
    match keyword {
        "d" | "Tr" if !(0.0..=1.0).contains(&first) => Some(format!(
            "{first} is outside 0..1 (the share of light {})",
            if keyword == "d" {
                "the surface stops"
            } else {
                "that passes"
            }
        )),
        "Ni" if first <= 0.0 => Some(format!(
            "an index of refraction must be above 0, got {first}"
        )),
        "Tf" => {
            let numbers: Vec<f32> = values.iter().map_while(|w| w.parse().ok()).collect();
            if !matches!(numbers.len(), 1 | 3) {
                Some(format!(
                    "expected r g b (or one number), got {} number(s)",
                    numbers.len()
                ))
            } else if numbers.iter().any(|&x| x < 0.0) {
                Some("a transmission filter must not be negative".into())
            } else {
                None
            }
        }
        _ => None,
    }
}

/// The glass of an MTL entry whose lines [`mtl_value_problem`] passed.
pub(super) fn glass_from_mtl(m: &tobj::Material) -> Option<Glass> {
    let tr = |key: &str| -> Option<Vec<f32>> {
        let text = m.unknown_param.get(key)?;
        Some(
            text.split_whitespace()
                .map_while(|w| w.parse().ok())
                .collect(),
        )
    };
    let transparency = match m.dissolve {
        Some(d) => 1.0 - d,
        None => tr("Tr").and_then(|v| v.first().copied()).unwrap_or(0.0),
    };
    let filter = match tr("Tf").as_deref() {
        Some(&[grey]) => Vec3::splat(grey),
        Some(&[r, g, b]) => Vec3::new(r, g, b),
        _ => Vec3::ONE,
    };
    let refracts = matches!(m.illumination_model, Some(4 | 6 | 7));
    let ior = match m.optical_density {
        Some(ni) if refracts => ni,
        _ => 1.0,
    };
    Glass::new(transparency.clamp(0.0, 1.0), ior, filter)
        .ok()
        .flatten()
}

/// Fresnel reflectance of a smooth dielectric for unpolarised light (the
/// exact formula, the mean of the s and p reflectances, not Schlick's
/// approximation), and the refracted direction; `None` for total internal
/// reflection. `d` is the unit incoming direction, `n` the unit normal on
/// its side (`d . n <= 0`), `eta` the index of the side `d` comes from over
/// that of the other side.
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> (f32, Option<Vec3>) {
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return (1.0, None);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let reflectance = 0.5 * (rs * rs + rp * rp);
    let t = d * eta + n * (eta * cos_i - cos_t);
    (reflectance, Some(t.normalize()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_follows_snell_and_fresnel() {
        let n = Vec3::Y;
        // Straight in: no bending, reflectance ((1.5 - 1) / 2.5)^2 = 0.04.
        let (f, t) = refract(-Vec3::Y, n, 1.0 / 1.5);
        assert!((f - 0.04).abs() < 1e-6, "{f}");
        assert!((t.unwrap() + Vec3::Y).length() < 1e-6);
        // 45 degrees into glass: sin t = sin 45 / 1.5.
        let d = Vec3::new(1.0, -1.0, 0.0).normalize();
        let (f, t) = refract(d, n, 1.0 / 1.5);
        let t = t.unwrap();
        let sin_t = t.x / t.length();
        assert!((sin_t - (0.5f32.sqrt() / 1.5)).abs() < 1e-6, "{sin_t}");
        assert!(t.y < 0.0);
        // Exact Fresnel at 45 degrees, n = 1.5: Rs 0.0920, Rp 0.0085.
        assert!((f - 0.5 * (0.092_013 + 0.008_466)).abs() < 1e-4, "{f}");
        // From inside, beyond the critical angle (41.8 degrees): all
        // reflected.
        let steep = Vec3::new(0.8, -0.6, 0.0);
        assert_eq!(refract(steep, n, 1.5), (1.0, None));
        // Index 1: straight through, nothing reflected.
        let (f, t) = refract(d, n, 1.0);
        assert_eq!(f, 0.0);
        assert!((t.unwrap() - d).length() < 1e-6);
    }

    #[test]
    fn bad_glass_values_name_their_field() {
        assert_eq!(Glass::new(0.0, 1.5, Vec3::ONE), Ok(None));
        assert_eq!(
            Glass::new(1.5, 1.5, Vec3::ONE).unwrap_err().0,
            "transparency"
        );
        assert_eq!(Glass::new(0.5, 0.0, Vec3::ONE).unwrap_err().0, "ior");
        assert_eq!(Glass::new(0.5, -1.0, Vec3::ONE).unwrap_err().0, "ior");
        assert_eq!(
            Glass::new(0.5, 1.5, Vec3::new(1.0, -1.0, 0.0))
                .unwrap_err()
                .0,
            "transmission_filter"
        );
        assert!(mtl_value_problem("Ni", &["0"]).is_some());
        assert!(mtl_value_problem("Ni", &["-1.5"]).is_some());
        assert!(mtl_value_problem("Ni", &["1.5"]).is_none());
        assert!(mtl_value_problem("d", &["1.2"]).is_some());
        assert!(mtl_value_problem("d", &["-0.1"]).is_some());
        assert!(mtl_value_problem("d", &["0.3"]).is_none());
        assert!(mtl_value_problem("Tf", &["1", "2"]).is_some());
        assert!(mtl_value_problem("Tf", &["0.9", "1", "0.9"]).is_none());
    }
}
