//! What a run will take in memory, known before it starts, so that a run
//! the machine cannot hold is refused with the figure instead of failing
//! (or swapping) hours in.
//!
//! Promises: the estimate is the sum of its named parts, each from the
//! sizes of the structures it counts; it is an estimate, compared with the
//! peak a run measures ([`peak_resident_bytes`]), not a bound.

use super::Animator;
use crate::reuse::ostc::Ostc;

/// The program, its thread stacks and the scene's own structures, before
/// any picture (measured: about 13 MB for the paper's scene).
const PROGRAM_BYTES: f64 = 16e6;

/// A view's pixel in the frame loop: the linear frame, its 8-bit output,
/// and the colours of its samples as they are traced (accumulated a group
/// at a time, so more samples a pixel cost no more).
const FRAME_BYTES_PER_PIXEL: f64 = 32.0;

/// The parts of a run's memory, in bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryEstimate {
    pub parts: Vec<(&'static str, f64)>,
}

impl MemoryEstimate {
    pub fn total(&self) -> f64 {
        self.parts.iter().map(|(_, bytes)| bytes).sum()
    }

    /// `14.2 GB (frames 10.7 GB, store 3.2 GB, ...)`: the parts above a
    /// hundredth of the whole.
    pub fn describe(&self) -> String {
        let total = self.total();
        let parts: Vec<String> = self
            .parts
            .iter()
            .filter(|(_, bytes)| *bytes >= total / 100.0)
            .map(|(name, bytes)| format!("{name} {}", bytes_text(*bytes)))
            .collect();
        format!("{} ({})", bytes_text(total), parts.join(", "))
    }
}

/// Bytes in the unit that reads best: `812 MB`, `14.2 GB`.
pub fn bytes_text(bytes: f64) -> String {
    if bytes >= 1e9 {
        format!("{:.1} GB", bytes / 1e9)
    } else {
        format!("{:.0} MB", (bytes / 1e6).max(1.0))
    }
}

impl MemoryEstimate {
    /// A single picture of `width` by `height` pixels, traced in full.
    pub fn picture(width: u32, height: u32) -> MemoryEstimate {
        let pixels = f64::from(width) * f64::from(height);
        MemoryEstimate {
            parts: vec![
                ("program", PROGRAM_BYTES),
                ("frame", pixels * FRAME_BYTES_PER_PIXEL),
            ],
        }
    }
}

impl Animator<'_> {
    /// What the run will hold at most: its views' frames and traced
    /// samples, the store, OSTC's bookkeeping and `--verify`'s renders.
    pub fn memory_estimate(&self) -> MemoryEstimate {
        let first = self.options.frames.start;
        let views = self.views(first);
        let run = self.run();
        let pixels: f64 = views
            .iter()
            .map(|view| f64::from(view.pose.camera.width) * f64::from(view.pose.camera.height))
            .sum();
        let samples = pixels * f64::from(self.base.samples.count());
        let mut parts = vec![
            ("program", PROGRAM_BYTES),
            ("frames", pixels * FRAME_BYTES_PER_PIXEL),
        ];
        if self.options.techniques.buffered() {
            parts.push(("store", self.plan.store_bytes(&run, &views)));
        }
        if run.ostc_keeps() {
            parts.push(("OSTC", Ostc::recorded_bytes(samples)));
        }
        if self.options.linear {
            // The full render and the one of a scene built afresh it is
            // compared with, and the converged reference.
            parts.push(("verify", 3.0 * pixels * FRAME_BYTES_PER_PIXEL));
        }
        MemoryEstimate { parts }
    }
}

/// The most memory the process has held so far (Linux's `VmHWM`), if
/// known.
pub fn peak_resident_bytes() -> Option<f64> {
    kilobytes_field("/proc/self/status", "VmHWM:")
}

/// The memory the machine can give a new run without swapping (Linux's
/// `MemAvailable`), if known.
pub fn available_bytes() -> Option<f64> {
    kilobytes_field("/proc/meminfo", "MemAvailable:")
}

/// A `NAME:   1234 kB` field of a /proc file, in bytes.
fn kilobytes_field(path: &str, name: &str) -> Option<f64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|line| line.starts_with(name))?;
    let kilobytes: f64 = line[name.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kilobytes * 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_estimate_names_its_large_parts() {
        let estimate = MemoryEstimate {
            parts: vec![("frames", 10.7e9), ("store", 3.2e9), ("program", 16e6)],
        };
        assert_eq!(
            estimate.describe(),
            "13.9 GB (frames 10.7 GB, store 3.2 GB)"
        );
        assert_eq!(bytes_text(0.2e6), "1 MB");
    }

    #[test]
    fn this_process_has_a_peak_and_the_machine_memory() {
        assert!(peak_resident_bytes().is_some_and(|bytes| bytes > 1e6));
        assert!(available_bytes().is_some_and(|bytes| bytes > 1e6));
    }
}
