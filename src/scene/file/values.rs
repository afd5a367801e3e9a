//! The value checks every table shares: finite triples, points within the
//! scene's extent, colours.
//!
//! Promises: each returns the checked value or a message for the user,
//! which the caller places at its table's file, line and field.

use glam::Vec3;

use crate::geometry::{within_world, WORLD_LIMIT};

/// Three finite numbers.
pub(super) fn finite3(values: [f32; 3]) -> Result<Vec3, String> {
    let v = Vec3::from_array(values);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("must be finite, got {values:?}"))
    }
}

/// A point of the scene: finite and within its extent.
pub(super) fn world3(values: [f32; 3]) -> Result<Vec3, String> {
    let v = finite3(values)?;
    if within_world(v) {
        Ok(v)
    } else {
        Err(format!(
            "{values:?} lies beyond the scene's extent (within ±{WORLD_LIMIT:e} of the origin)"
        ))
    }
}

/// A colour: finite and not negative.
pub(super) fn colour(values: [f32; 3]) -> Result<Vec3, String> {
    let v = finite3(values)?;
    if v.min_element() < 0.0 {
        return Err(format!(
            "colour components must not be negative, got {values:?}"
        ));
    }
    Ok(v)
}
