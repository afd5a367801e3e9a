//! What a run of the frame loop is asked to do, settled before its first
//! frame.

use super::ostc::DEFAULT_VOXELS;
use super::pan::FractionalPan;
use super::regions::RegionGrid;
use super::rsvp::RsvpKnobs;
use crate::aov::AovSet;

/// One reuse technique.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Technique {
    Pan,
    Rsvp,
    Ostc,
}

impl Technique {
    pub const ALL: [Technique; 3] = [Technique::Pan, Technique::Rsvp, Technique::Ostc];

    pub fn name(self) -> &'static str {
        match self {
            Technique::Pan => "pan",
            Technique::Rsvp => "rsvp",
            Technique::Ostc => "ostc",
        }
    }
}

/// Which reuse techniques a run may use (`--mode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Techniques {
    pub pan: bool,
    /// RSVP: viewports resample the lazily traced camera sample buffer.
    pub rsvp: bool,
    pub ostc: bool,
}

impl Techniques {
    pub const FULL: Techniques = Techniques {
        pan: false,
        rsvp: false,
        ostc: false,
    };
    /// Everything the timeline allows.
    pub const AUTO: Techniques = Techniques {
        pan: true,
        rsvp: true,
        ostc: true,
    };

    /// Parses `full`, `auto`, or a comma list of techniques (`pan`, `rsvp`,
    /// `ostc`); `full` and `auto` stand alone.
    pub fn parse(text: &str) -> Result<Techniques, String> {
        let mut techniques = Techniques::FULL;
        let words: Vec<&str> = text.split(',').map(str::trim).collect();
        if let [_, _, ..] = words[..] {
            if let Some(alone) = words.iter().find(|w| matches!(**w, "full" | "auto")) {
                return Err(format!(
                    "'{alone}' stands alone (it says which techniques run): give it by itself, \
                     or a list of pan, rsvp, ostc"
                ));
            }
        }
        for word in words {
            match word {
                "full" => {}
                "auto" => techniques = Techniques::AUTO,
                "pan" => techniques.pan = true,
                "ostc" => techniques.ostc = true,
                "rsvp" => techniques.rsvp = true,
                other => {
                    return Err(format!(
                        "unknown mode '{other}' (expected full, auto, or a comma list of: pan, rsvp, ostc)"
                    ))
                }
            }
        }
        Ok(techniques)
    }

    /// Whether `technique` is asked for.
    pub fn has(self, technique: Technique) -> bool {
        match technique {
            Technique::Pan => self.pan,
            Technique::Rsvp => self.rsvp,
            Technique::Ostc => self.ostc,
        }
    }

    /// Whether a camera image may be kept in a buffer.
    pub fn buffered(self) -> bool {
        self.pan || self.ostc
    }
}

/// OSTC settings (`--regions`, `--ostc-voxels`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OstcSettings {
    /// The grid asked for; None: the one measured fastest for the store
    /// that keeps the samples (see [`super::SampleStore::ostc_regions`]).
    pub regions: Option<RegionGrid>,
    pub voxels: u32,
}

impl Default for OstcSettings {
    fn default() -> Self {
        OstcSettings {
            regions: None,
            voxels: DEFAULT_VOXELS,
        }
    }
}

/// Everything a run of the frame loop is asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    pub techniques: Techniques,
    /// The frames of the run (they size the pan buffer's rows).
    pub frames: std::ops::Range<u32>,
    /// Whether frames come in linear colour too, not only as 8-bit sRGB
    /// (for bit-exact checks; without, reused frames skip copying 12
    /// bytes per pixel).
    pub linear: bool,
    pub fractional_pan: FractionalPan,
    pub ostc: OstcSettings,
    pub rsvp: RsvpKnobs,
    /// Whether each view also comes with its picture painted black where
    /// the frame traced samples (the paper's figure 4).
    pub traced_images: bool,
    /// The arbitrary output variables each view comes with (none: no work
    /// at all for them).
    pub aovs: AovSet,
    /// The most bytes a store's kept samples may take (None: no cap).
    /// RSVP's buffer then evicts the samples read least recently, traced
    /// again, the same, when read again.
    pub sample_memory: Option<u64>,
}

impl Options {
    /// `techniques` over `frames`, everything else at its default: linear
    /// colour on, snapped pans, default OSTC and RSVP knobs.
    pub fn new(techniques: Techniques, frames: std::ops::Range<u32>) -> Options {
        Options {
            techniques,
            frames,
            linear: true,
            fractional_pan: FractionalPan::Snap,
            ostc: OstcSettings::default(),
            rsvp: RsvpKnobs::default(),
            traced_images: false,
            aovs: AovSet::NONE,
            sample_memory: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse() {
        assert_eq!(Techniques::parse("full"), Ok(Techniques::FULL));
        assert_eq!(Techniques::parse("auto"), Ok(Techniques::AUTO));
        assert_eq!(
            Techniques::parse("pan"),
            Ok(Techniques {
                pan: true,
                rsvp: false,
                ostc: false
            })
        );
        assert_eq!(
            Techniques::parse("rsvp,pan"),
            Ok(Techniques {
                pan: true,
                rsvp: true,
                ostc: false
            })
        );
        assert_eq!(Techniques::parse("pan,ostc,rsvp"), Ok(Techniques::AUTO));
        assert!(Techniques::parse("zoom").is_err());
        // `full` with techniques once ran the techniques, silently.
        for mixed in ["full,pan", "pan,full", "auto,ostc", "full,auto"] {
            let err = Techniques::parse(mixed).unwrap_err();
            assert!(err.contains("stands alone"), "{mixed}: {err}");
        }
    }
}
