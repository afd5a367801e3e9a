//! The lab: measurements of what the frame loop saves and what its
//! approximations cost. The paper's experiments (`bench`), the sweep of
//! every speed-for-accuracy knob (`tradeoff`), Embree checked against the
//! pure-Rust grid (`validate`), and the reports and plots they write.

pub mod bench;
pub mod plot;
pub mod report;
pub mod tradeoff;
pub mod validate;
