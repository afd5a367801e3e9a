//! When in the shutter each camera ray is cast (motion blur).
//!
//! Promise: a camera ray's shutter time is a pure function of its pinhole
//! ray (through [`super::draws`]: a hash of the ray's bits, so of the
//! world-anchored sample), a fixed seed and where the sample stands among
//! its neighbours ([`PixelStrata`]), so a reused sample is cast when a
//! fresh trace of it is, in every frame. Stratified:
//! - the sub-samples of a square count n x n draw one in each of n^2
//!   equal intervals of the shutter (their pixel cells dealt a fixed
//!   shuffle of the intervals, its own);
//! - the RSVP lattice's samples draw one in each of 4^m intervals across
//!   every aligned 2^m x 2^m block of any level
//!   ([`super::strata::lattice_digits`]);
//!
//! each jittered inside its interval by the key.

use super::draws::{key_draw, ray_keys, ONE_BELOW};
use super::strata::{CellDeal, PixelStrata};
use crate::camera::CameraMotion;
use crate::ray::{LaneMask, RayPacket};
use crate::timeline::Shutter;

/// The seed shutter times are drawn from.
const SEED: u64 = 0x7368_7574_2074_696d;

/// The deal of the shutter's intervals to a pixel's sub-samples.
static SHUTTER_INTERVALS: CellDeal = CellDeal::new(0x7368_7574_2063_656c);

/// `rays` (pinhole camera rays) each cast at its shutter time, by the
/// camera as it stands then when it moves (lanes outside `mask` as they
/// were).
pub(super) fn timed_rays(
    rays: &RayPacket,
    mask: LaneMask,
    strata: Option<&PixelStrata>,
    camera: Option<&CameraMotion>,
) -> RayPacket {
    let keys = ray_keys(rays, 0);
    std::array::from_fn(|lane| {
        if mask & (1 << lane) == 0 {
            return rays[lane];
        }
        let u = key_draw(keys[lane], SEED, &[0]);
        // f32 rounding can carry an interval's last draw onto its end.
        let time = SHUTTER_INTERVALS
            .place_on_line(u, strata.map(|s| s.lane(lane)))
            .min(ONE_BELOW);
        let ray = rays[lane].at_time(time);
        camera.map_or(ray, |camera| camera.moved(&ray))
    })
}

/// The shutter time (0 at the opening, 1 at the closing) of the frame's
/// instant, the nearest end when the shutter does not span it.
pub(super) fn time_of_instant(shutter: &Shutter) -> f32 {
    let time = -shutter.open / (shutter.close - shutter.open);
    (time as f32).clamp(0.0, ONE_BELOW)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::ray::{Ray, PACKET_WIDTH};

    fn packet(seed: u32) -> RayPacket {
        std::array::from_fn(|lane| {
            let x = (seed * 8 + lane as u32) as f32 * 0.013;
            Ray::new(Vec3::new(0.5, 1.0, 2.0), Vec3::new(x, 0.2, -1.0))
        })
    }

    #[test]
    fn times_lie_in_the_shutter_and_depend_on_the_ray_alone() {
        let rays = packet(3);
        let timed = timed_rays(&rays, 0xff, None, None);
        let again = timed_rays(&rays, 0xff, None, None);
        for lane in 0..PACKET_WIDTH {
            assert!((0.0..1.0).contains(&timed[lane].time));
            assert_eq!(timed[lane].time.to_bits(), again[lane].time.to_bits());
            assert_eq!(
                (timed[lane].origin, timed[lane].dir),
                (rays[lane].origin, rays[lane].dir)
            );
        }
        // Lanes outside the mask are left as they were.
        let some = timed_rays(&rays, 0b1, None, None);
        assert_eq!(some[1], rays[1]);
    }

    #[test]
    fn a_pixels_sub_samples_draw_one_time_in_each_interval() {
        let side = 2u32;
        let mut intervals = Vec::new();
        for (index, cell) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let strata = PixelStrata::new(side, [(cell.0, cell.1); PACKET_WIDTH]);
            let timed = timed_rays(&packet(index as u32), 0xff, Some(&strata), None);
            intervals.push((timed[0].time * 4.0) as u32);
        }
        intervals.sort_unstable();
        assert_eq!(intervals, vec![0, 1, 2, 3]);
    }
}
