//! `retrace view`: the frame loop behind a window a person can drag, zoom
//! and play, or behind a script of the same input without a display.
//!
//! Input becomes a view state ([`state`]); a render thread ([`worker`])
//! renders the latest state through the one frame loop, so a drag of an
//! equal-angle camera is a Panimation pan, a zoom an RSVP viewport, and a
//! moving object OSTC's; the window ([`window`]) or a script ([`script`])
//! shows or saves what it finishes, with its keys listed and drawn as
//! help ([`help`]).

pub mod help;
pub mod refine;
pub mod script;
pub mod state;
pub mod window;
pub mod worker;

pub use state::{Effect, Input, Key, ViewState, Viewer};
pub use worker::{Picture, RenderThread};

use std::path::{Path, PathBuf};

/// The first `view_NNNN.png` in `folder` that does not exist yet: where
/// `s` saves, never over an earlier picture.
pub fn next_save_path(folder: &Path) -> PathBuf {
    (1..)
        .map(|n| folder.join(format!("view_{n:04}.png")))
        .find(|path| !path.exists())
        .expect("some number is free")
}
