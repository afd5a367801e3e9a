//! Shared by the integration tests: run a test body on every backend.

/// Runs each test body once per backend, as `embree::name` and `grid::name`,
/// with `$backend` bound to the backend's `BackendKind`.
#[macro_export]
macro_rules! on_every_backend {
    ($($name:ident($backend:ident) $body:block)*) => {
        mod embree {
            use super::*;
            $(#[test] fn $name() { let $backend = retrace::accel::BackendKind::Embree; $body })*
        }
        mod grid {
            use super::*;
            $(#[test] fn $name() { let $backend = retrace::accel::BackendKind::Grid; $body })*
        }
    };
}
