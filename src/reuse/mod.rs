//! The reuse algorithms: what a frame can take from earlier frames instead
//! of tracing. Reuse code never calls Embree: it decides which samples must
//! be traced and hands them to [`crate::render`].

pub mod ostc;
pub mod pan;
pub mod regions;
pub mod rsvp;
