//! Wall-clock time as the statistics report it: milliseconds as `f64`,
//! converted in one place.

use std::time::{Duration, Instant};

/// Time since it was started, in milliseconds.
#[derive(Clone, Copy, Debug)]
pub struct Stopwatch(Instant);

impl Stopwatch {
    pub fn start() -> Stopwatch {
        Stopwatch(Instant::now())
    }

    /// Milliseconds since [`Stopwatch::start`].
    pub fn ms(&self) -> f64 {
        ms(self.0.elapsed())
    }
}

/// `duration` in milliseconds.
pub fn ms(duration: Duration) -> f64 {
    duration.as_secs_f64() * 1e3
}

/// `ms` milliseconds as a duration (negative as zero).
pub fn duration(ms: f64) -> Duration {
    Duration::from_secs_f64(ms.max(0.0) / 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn milliseconds_round_trip_through_durations() {
        assert_eq!(ms(Duration::from_micros(2500)), 2.5);
        assert_eq!(duration(2.5), Duration::from_micros(2500));
        assert_eq!(duration(-1.0), Duration::ZERO);
    }

    #[test]
    fn a_stopwatch_counts_up_from_its_start() {
        let watch = Stopwatch::start();
        std::thread::sleep(Duration::from_millis(2));
        assert!(watch.ms() >= 2.0);
    }
}
