//! Windows on strata: a view whose corner sits between cells, each pixel
//! resolved from the strata it covers rather than copied from one cell.
//!
//! Promises: the buffer and a fresh render resolve a window through the
//! one [`resolve`], so they agree bit for bit; a window on whole cells,
//! snapped, resolves each pixel to its cell's own colour bit for bit (the
//! strata summed in the order [`crate::render::trace_group`] sums them).

use glam::Vec3;
use rayon::prelude::*;

use super::{Lattice, Window};
use crate::color::srgb_table;
use crate::render::{trace_groups, Frame, SampleGroup, Strata, GROUP_HEIGHT, GROUP_WIDTH};
use crate::shade::{RayCounts, Shader};

impl Window {
    /// Whether every pixel is one cell of the lattice (neither offset by
    /// strata nor blended).
    pub fn on_whole_cells(&self) -> bool {
        self.strata_offset == (0, 0) && self.blend == (0.0, 0.0)
    }

    /// The window of whole cells holding every stratum this one reads: a
    /// cell wider (taller) where it is offset or blended across (down).
    pub fn cells(&self) -> Window {
        let (x, y) = self.strata_offset;
        let (blend_x, blend_y) = self.blend;
        Window {
            width: self.width + u32::from(x != 0 || blend_x > 0.0),
            height: self.height + u32::from(y != 0 || blend_y > 0.0),
            strata_offset: (0, 0),
            strata_side: 1,
            blend: (0.0, 0.0),
            ..*self
        }
    }

    /// The stratum at the image's corner, on the lattice of its strata.
    pub(super) fn first_stratum(&self) -> (i64, i64) {
        let side = self.strata_side;
        (
            self.col * side + self.strata_offset.0,
            self.row * side + self.strata_offset.1,
        )
    }

    /// The columns and rows of strata the window reads: a stratum more
    /// than its pixels' along a blended axis.
    pub(super) fn strata_span(&self) -> (i64, i64) {
        let side = self.strata_side;
        let span = |pixels: u32, blend: f32| i64::from(pixels) * side + i64::from(blend > 0.0);
        (
            span(self.width, self.blend.0),
            span(self.height, self.blend.1),
        )
    }
}

/// How a pixel weighs the strata it reads along one axis: each of its
/// `side` strata fully; blended, the box moved `blend` of a stratum on,
/// over `side + 1` strata with the first and last weighed by how much of
/// them it covers.
fn weights(side: usize, blend: f32) -> Vec<f32> {
    if blend == 0.0 {
        return vec![1.0; side];
    }
    let mut weights = vec![1.0; side + 1];
    weights[0] = 1.0 - blend;
    weights[side] = blend;
    weights
}

/// The window's pixels from its strata: each the box over the strata it
/// reads ([`weights`]), summed row by row from the top left as
/// [`crate::render::trace_group`] sums a cell's strata (a weight of one
/// multiplies exactly), over `side` x `side`. `row(j)` is the j-th row of
/// strata from the window's top, where stratum k from its left lies at
/// `columns[k]`. Returns, in one pass over the rows, the linear pixels
/// when `linear` is set and the 8-bit sRGB image.
pub(super) fn resolve<'a>(
    window: &Window,
    side: usize,
    columns: &[usize],
    row: impl Fn(usize) -> &'a [[f32; 3]] + Sync,
    linear: bool,
) -> (Option<Vec<Vec3>>, Vec<u8>) {
    let (width, height) = (window.width as usize, window.height as usize);
    let scale = 1.0 / (side * side) as f32;
    let (across, down) = (weights(side, window.blend.0), weights(side, window.blend.1));
    let srgb = srgb_table();
    // Unless the window wraps round the turn its strata are one run of
    // each row: read from a slice, without an index a stratum.
    let first = columns.first().copied().unwrap_or(0);
    let contiguous = columns.iter().enumerate().all(|(k, &c)| c == first + k);
    let mut pixels = vec![Vec3::ZERO; if linear { width * height } else { 0 }];
    let mut pixel_rows: Vec<Option<&mut [Vec3]>> = if linear {
        pixels.chunks_mut(width).map(Some).collect()
    } else {
        (0..height).map(|_| None).collect()
    };
    let mut bytes = vec![0u8; width * height * 3];
    bytes
        .par_chunks_mut(width * 3)
        .zip(pixel_rows.par_iter_mut())
        .enumerate()
        .for_each(|(y, (bytes, linear_row))| {
            let mut sums = vec![Vec3::ZERO; width];
            for (j, &down) in down.iter().enumerate() {
                let strata = row(y * side + j);
                let weights: Vec<f32> = across.iter().map(|&across| across * down).collect();
                if contiguous {
                    let run = &strata[first..first + columns.len()];
                    let pixels = run.windows(weights.len()).step_by(side);
                    for (sum, strata) in sums.iter_mut().zip(pixels) {
                        for (&stratum, &weight) in strata.iter().zip(&weights) {
                            *sum += Vec3::from(stratum) * weight;
                        }
                    }
                } else {
                    let pixels = columns.windows(weights.len()).step_by(side);
                    for (sum, columns) in sums.iter_mut().zip(pixels) {
                        for (&column, &weight) in columns.iter().zip(&weights) {
                            *sum += Vec3::from(strata[column]) * weight;
                        }
                    }
                }
            }
            for (sum, bytes) in sums.iter_mut().zip(bytes.chunks_exact_mut(3)) {
                *sum *= scale;
                bytes.copy_from_slice(&sum.to_array().map(|c| srgb.encode(c)));
            }
            if let Some(linear_row) = linear_row {
                linear_row.copy_from_slice(&sums);
            }
        });
    drop(pixel_rows);
    (linear.then_some(pixels), bytes)
}

/// [`super::render_window`] for a window on strata: its strata traced as
/// groups of their own ([`Strata`]; the cells themselves at one stratum a
/// cell), then resolved as the buffer resolves them.
pub(super) fn render<L: Lattice>(
    shader: &Shader,
    lattice: &L,
    window: &Window,
) -> (Frame, RayCounts) {
    let side = window.strata_side;
    let (first_col, first_row) = window.first_stratum();
    let (width, height) = window.strata_span();
    let groups = SampleGroup::covering(first_col..first_col + width, first_row..first_row + height);
    let (colors, counts) = if side == 1 {
        trace_groups(shader, lattice, &groups)
    } else {
        trace_groups(shader, &Strata::new(lattice), &groups)
    };
    let mut strata = vec![[0.0; 3]; (width * height) as usize];
    for (group, colors) in groups.iter().zip(&colors) {
        for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
            let (x, y) = (col - first_col, row - first_row);
            if (0..width).contains(&x) && (0..height).contains(&y) {
                strata[(y * width + x) as usize] = colors[lane].to_array();
            }
        }
    }
    let columns: Vec<usize> = (0..width as usize).collect();
    let row = |y: usize| &strata[y * width as usize..(y + 1) * width as usize];
    let (pixels, _) = resolve(window, side as usize, &columns, row, true);
    let frame = Frame {
        width: window.width,
        height: window.height,
        pixels: pixels.expect("asked for"),
    };
    (frame, counts)
}

/// The pixels of windows snapped to one offset of strata, as resolved so
/// far: a steady pan keeps its offset for many frames (E1's 46.08 strata
/// a frame at 4 samples a pixel), and then copies what it resolved before
/// as a pan on whole cells copies cells. Laid out as the buffer's cells:
/// entry (col, row) is the pixel whose corner is stratum (col n + x,
/// row n + y) for the offset (x, y).
pub(super) struct ResolvedStrata {
    offset: (i64, i64),
    colors: Vec<[f32; 3]>,
    bytes: Vec<[u8; 3]>,
    /// Per entry: resolved from the strata as they are now?
    valid: Vec<bool>,
}

impl ResolvedStrata {
    pub(super) fn new(entries: usize) -> ResolvedStrata {
        ResolvedStrata {
            offset: (0, 0),
            colors: vec![[0.0; 3]; entries],
            bytes: vec![[0; 3]; entries],
            valid: vec![false; entries],
        }
    }

    /// Forgets the entries reading any cell of `group` (of cells; `turn`
    /// cells a row, rows from `first_row`): theirs and, as an entry reads
    /// its cell and the next across and down, those a cell before.
    pub(super) fn forget(&mut self, group: SampleGroup, first_row: i64, turn: i64) {
        let rows = self.valid.len() as i64 / turn;
        let (gw, gh) = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
        for row in group.row - 1..group.row + gh {
            let row = row - first_row;
            if !(0..rows).contains(&row) {
                continue;
            }
            for col in group.col - 1..group.col + gw {
                self.valid[(row * turn + col.rem_euclid(turn)) as usize] = false;
            }
        }
    }

    /// The window's pixels, resolving first those not resolved at its
    /// offset (all of them when the offset changed) from `strata` (`side`
    /// a cell, rows of `turn * side` from stratum row `first_row * side`),
    /// `linear` as [`resolve`] gives them.
    pub(super) fn window(
        &mut self,
        window: &Window,
        strata: &[[f32; 3]],
        (first_row, turn): (i64, i64),
        linear: bool,
    ) -> (Option<Vec<Vec3>>, Vec<u8>) {
        debug_assert!(window.blend == (0.0, 0.0));
        if self.offset != window.strata_offset {
            self.offset = window.strata_offset;
            self.valid.fill(false);
        }
        let side = window.strata_side;
        let (turn_u, n) = (turn as usize, side as usize);
        let strata_turn = turn_u * n;
        let scale = 1.0 / (n * n) as f32;
        let srgb = srgb_table();
        let (x0, y0) = self.offset;
        // The window's rows of entries, resolved in parallel.
        let top = (window.row - first_row) as usize;
        let rows = top..top + window.height as usize;
        let span = rows.start * turn_u..rows.end * turn_u;
        (self.colors[span.clone()].par_chunks_mut(turn_u))
            .zip(self.bytes[span.clone()].par_chunks_mut(turn_u))
            .zip(self.valid[span].par_chunks_mut(turn_u))
            .enumerate()
            .for_each(|(y, ((colors, bytes), valid))| {
                let row = (top + y) as i64 + first_row;
                let stratum_row = |j: i64| {
                    let at = ((row * side + y0 + j) - first_row * side) as usize * strata_turn;
                    &strata[at..at + strata_turn]
                };
                let first = window.col.rem_euclid(turn) as usize;
                let cols = (first..turn_u).chain(0..first).cycle();
                for col in cols.take(window.width as usize) {
                    if valid[col] {
                        continue;
                    }
                    let mut sum = Vec3::ZERO;
                    for j in 0..side {
                        let strata = stratum_row(j);
                        for i in 0..side {
                            let at = (col as i64 * side + x0 + i).rem_euclid(turn * side);
                            sum += Vec3::from(strata[at as usize]);
                        }
                    }
                    sum *= scale;
                    colors[col] = sum.to_array();
                    bytes[col] = sum.to_array().map(|c| srgb.encode(c));
                    valid[col] = true;
                }
            });
        copy_rows(window, &self.colors, &self.bytes, (first_row, turn), linear)
    }
}

/// A window's pixels copied out of cell-shaped stores (`turn` entries a
/// row, rows from `first_row`), whole runs up to each wrap of the turn.
pub(super) fn copy_rows(
    window: &Window,
    colors: &[[f32; 3]],
    bytes: &[[u8; 3]],
    (first_row, turn): (i64, i64),
    linear: bool,
) -> (Option<Vec<Vec3>>, Vec<u8>) {
    let (width, height) = (window.width as usize, window.height as usize);
    let mut pixels = Vec::with_capacity(if linear { width * height } else { 0 });
    let mut out: Vec<u8> = Vec::with_capacity(width * height * 3);
    let turn = turn as usize;
    for y in 0..height {
        let row_start = (window.row + y as i64 - first_row) as usize * turn;
        let mut x = 0usize;
        while x < width {
            let col = (window.col + x as i64).rem_euclid(turn as i64) as usize;
            let run = (turn - col).min(width - x);
            let entries = row_start + col..row_start + col + run;
            if linear {
                pixels.extend(colors[entries.clone()].iter().map(|&c| Vec3::from(c)));
            }
            out.extend_from_slice(bytes[entries].as_flattened());
            x += run;
        }
    }
    (linear.then_some(pixels), out)
}
