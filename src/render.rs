//! Turning samples into colours: full frames, and "trace just these sample
//! groups" for the reuse algorithms. The one way samples get traced.
//!
//! Samples are traced in fixed groups of 4x2 (one 8-wide packet), aligned to
//! multiples of 4 columns and 2 rows of the sample lattice; with several
//! sub-samples a cell, a group is one packet per sub-sample index or, for
//! square counts, one per group of its strata ([`Strata`]). Embree does not
//! promise that a ray gives bit-identical results in a different packet, so
//! a ray is always traced with the same seven neighbours: a partial
//! re-trace then equals a full render bit for bit.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::Intersector;
use crate::camera::{Camera, RayTable};
use crate::color::srgb_table;
use crate::ray::{LaneMask, Ray, RayPacket, PACKET_WIDTH};
use crate::sampling::PixelSamples;
use crate::scene::Scene;
use crate::shade::{PixelStrata, RayCounts, RayObserver, Shader};

pub const GROUP_WIDTH: u32 = 4;
pub const GROUP_HEIGHT: u32 = 2;
const _: () = assert!((GROUP_WIDTH * GROUP_HEIGHT) as usize == PACKET_WIDTH);

/// The aligned group holding a sample: column and row of its top-left sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SampleGroup {
    pub col: i64,
    pub row: i64,
}

impl SampleGroup {
    pub fn containing(col: i64, row: i64) -> SampleGroup {
        SampleGroup {
            col: col.div_euclid(i64::from(GROUP_WIDTH)) * i64::from(GROUP_WIDTH),
            row: row.div_euclid(i64::from(GROUP_HEIGHT)) * i64::from(GROUP_HEIGHT),
        }
    }

    /// (column, row) of each lane.
    pub fn lane_samples(self) -> [(i64, i64); PACKET_WIDTH] {
        std::array::from_fn(|lane| {
            (
                self.col + (lane as i64 % i64::from(GROUP_WIDTH)),
                self.row + (lane as i64 / i64::from(GROUP_WIDTH)),
            )
        })
    }

    /// The groups covering columns `cols` and rows `rows` (half-open).
    pub fn covering(cols: std::ops::Range<i64>, rows: std::ops::Range<i64>) -> Vec<SampleGroup> {
        if cols.is_empty() || rows.is_empty() {
            return Vec::new();
        }
        let first = SampleGroup::containing(cols.start, rows.start);
        let (gw, gh) = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
        let mut groups = Vec::new();
        let mut row = first.row;
        while row < rows.end {
            let mut col = first.col;
            while col < cols.end {
                groups.push(SampleGroup { col, row });
                col += gw;
            }
            row += gh;
        }
        groups
    }
}

/// Where primary rays come from: a sample lattice addressed by integer
/// column and row, each cell traced through its centre or, antialiased,
/// through [`PrimaryRays::samples`] sub-samples whose colours are
/// averaged (a box filter over the cell). None = no ray there (outside the
/// image, or outside what the projection covers).
pub trait PrimaryRays: Sync {
    /// The ray through the centre of cell (col, row).
    fn primary(&self, col: i64, row: i64) -> Option<Ray>;

    /// The rays of a whole group and the mask of lanes that have one. One
    /// dynamic call per packet: inside, `primary` is called on the concrete
    /// type and inlines (eight dynamic calls per packet cost more than the
    /// ray arithmetic).
    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        gather_group(self, group)
    }

    /// How many sub-samples each cell is traced with, and where.
    fn samples(&self) -> PixelSamples {
        PixelSamples::ONE
    }

    /// Where the cells of one-sample `group` stand for stratifying their
    /// draws, if anywhere: when this source's cells are the strata of
    /// another's square count n x n ([`Strata`]), cell (col, row) is a
    /// sub-sample in cell (col mod n, row mod n) of its pixel's grid.
    fn draw_strata(&self, group: SampleGroup) -> Option<PixelStrata> {
        let _ = group;
        None
    }

    /// The ray of sub-sample `index` of cell (col, row).
    fn sample(&self, col: i64, row: i64, index: u32) -> Option<Ray> {
        debug_assert_eq!(index, 0, "a source of one sample a cell");
        self.primary(col, row)
    }

    /// The rays of sub-sample `index` of every cell of `group`: a packet of
    /// the same sub-sample of eight neighbouring cells (counts that are not
    /// squares; see [`PrimaryRays::strata_group`] for the others).
    fn sample_group(&self, group: SampleGroup, index: u32) -> (RayPacket, LaneMask) {
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        let mut mask: LaneMask = 0;
        for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
            if let Some(ray) = self.sample(col, row, index) {
                rays[lane] = ray;
                mask |= 1 << lane;
            }
        }
        (rays, mask)
    }

    /// With a square count n x n, the rays of `strata`, a group of the
    /// lattice of strata (n times as dense along each axis, see
    /// [`Strata`]): eight neighbouring strata, so a packet stays within two
    /// cells at 4 samples a cell and within one from 16.
    fn strata_group(&self, strata: SampleGroup) -> (RayPacket, LaneMask) {
        let side = i64::from(self.samples().grid_side());
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        let mut mask: LaneMask = 0;
        for (lane, (col, row)) in strata.lane_samples().into_iter().enumerate() {
            let (cell, index) = stratum_cell(col, row, side);
            if let Some(ray) = self.sample(cell.0, cell.1, index) {
                rays[lane] = ray;
                mask |= 1 << lane;
            }
        }
        (rays, mask)
    }
}

/// The cell holding stratum (col, row) of a lattice of strata `side` times
/// as dense, and the stratum's sub-sample index in it (sub-sample k lies in
/// the cell's grid square (k % side, k / side): [`PixelSamples`]).
#[inline(always)]
pub fn stratum_cell(col: i64, row: i64, side: i64) -> ((i64, i64), u32) {
    if side & (side - 1) == 0 {
        // 4 and 16 sub-samples: shifts and masks, not divisions, on every
        // ray of a full render.
        let (shift, mask) = (side.trailing_zeros(), side - 1);
        let index = (row & mask) * side + (col & mask);
        return ((col >> shift, row >> shift), index as u32);
    }
    let cell = (col.div_euclid(side), row.div_euclid(side));
    let index = row.rem_euclid(side) * side + col.rem_euclid(side);
    (cell, index as u32)
}

/// A lattice's strata as a lattice of their own: with a square count of
/// n x n sub-samples a cell, cell (col, row) here is sub-sample
/// ((row % n) * n + col % n) of the source's cell (col / n, row / n), one
/// sample each. Tracing a source's groups and tracing its strata's groups
/// make the same packets ([`trace_group`]), so a store may keep strata and
/// re-trace a group of them (two pixels at 4 samples a pixel) where it
/// would otherwise re-trace a group of whole cells.
pub struct Strata<'a, P: ?Sized> {
    pub source: &'a P,
    side: i64,
}

impl<'a, P: PrimaryRays + ?Sized> Strata<'a, P> {
    /// The strata of `source`, whose count must be a square above one.
    pub fn new(source: &'a P) -> Strata<'a, P> {
        let side = source.samples().grid_side();
        assert!(side > 1, "strata of a source with a square count above one");
        Strata {
            source,
            side: i64::from(side),
        }
    }

    /// Strata along each side of a source cell.
    pub fn side(&self) -> u32 {
        self.side as u32
    }
}

impl<P: PrimaryRays + ?Sized> PrimaryRays for Strata<'_, P> {
    #[inline(always)]
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        let (cell, index) = stratum_cell(col, row, self.side);
        self.source.sample(cell.0, cell.1, index)
    }

    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        self.source.strata_group(group)
    }

    fn draw_strata(&self, group: SampleGroup) -> Option<PixelStrata> {
        Some(PixelStrata::new(self.side as u32, group.lane_samples()))
    }
}

/// A window of `width` x `height` cells onto `source`: cell (x, y) here
/// is `source`'s cell (col + x, row + y), and there is no ray outside the
/// window (a pan's picture on its lattice).
pub struct Shifted<P> {
    pub source: P,
    pub col: i64,
    pub row: i64,
    pub width: u32,
    pub height: u32,
}

impl<P: PrimaryRays> PrimaryRays for Shifted<P> {
    fn primary(&self, x: i64, y: i64) -> Option<Ray> {
        let inside =
            (0..i64::from(self.width)).contains(&x) && (0..i64::from(self.height)).contains(&y);
        if !inside {
            return None;
        }
        self.source.primary(self.col + x, self.row + y)
    }
}

/// The rays of `group`, one [`PrimaryRays::primary`] call per lane.
#[inline(always)]
fn gather_group<P: PrimaryRays + ?Sized>(source: &P, group: SampleGroup) -> (RayPacket, LaneMask) {
    let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
    let mut mask: LaneMask = 0;
    for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
        if let Some(ray) = source.primary(col, row) {
            rays[lane] = ray;
            mask |= 1 << lane;
        }
    }
    (rays, mask)
}

/// A camera's lattice is its image: one sample per pixel centre.
impl PrimaryRays for RayTable {
    #[inline(always)]
    fn primary(&self, col: i64, row: i64) -> Option<Ray> {
        let (width, height) = self.size();
        let inside = (0..i64::from(width)).contains(&col) && (0..i64::from(height)).contains(&row);
        if !inside {
            return None;
        }
        self.primary_ray(col as u32, row as u32)
    }

    /// A group inside the image (every group of a frame whose size is a
    /// multiple of the group's) is checked against the image once, not
    /// lane by lane.
    fn primary_group(&self, group: SampleGroup) -> (RayPacket, LaneMask) {
        let (width, height) = self.size();
        let inside = group.col >= 0
            && group.row >= 0
            && group.col + i64::from(GROUP_WIDTH) <= i64::from(width)
            && group.row + i64::from(GROUP_HEIGHT) <= i64::from(height);
        if !inside {
            return gather_group(self, group);
        }
        let (col, row) = (group.col as u32, group.row as u32);
        let mut rays = [Ray::INACTIVE; PACKET_WIDTH];
        let mut mask: LaneMask = 0;
        for (lane, ray) in rays.iter_mut().enumerate() {
            let lane_u32 = lane as u32;
            let sample =
                self.primary_ray(col + lane_u32 % GROUP_WIDTH, row + lane_u32 / GROUP_WIDTH);
            if let Some(sample) = sample {
                *ray = sample;
                mask |= 1 << lane;
            }
        }
        (rays, mask)
    }

    fn samples(&self) -> PixelSamples {
        RayTable::samples(self)
    }

    #[inline(always)]
    fn sample(&self, col: i64, row: i64, index: u32) -> Option<Ray> {
        let (width, height) = self.size();
        let inside = (0..i64::from(width)).contains(&col) && (0..i64::from(height)).contains(&row);
        if !inside {
            return None;
        }
        self.sample_ray(col as u32, row as u32, index)
    }
}

/// Traces one group: each cell's colour, the mean of its sub-samples'
/// (summed in index order, so the same bits every time); lanes without a
/// ray come back black.
///
/// With a square count n x n the packets are the n x n groups of the
/// group's strata ([`Strata`]): a packet holds neighbouring rays, and a
/// store keeping strata traces exactly these packets. Either way each
/// lane's cell of its pixel is read off its stratum's place on the lattice
/// of strata and handed to shading ([`Shader::shade_strata`]), so a
/// stratum shades alike whether traced in its cell's group or in a group
/// of strata.
pub fn trace_group(
    shader: &Shader,
    source: &dyn PrimaryRays,
    group: SampleGroup,
    counts: &mut RayCounts,
    mut observer: Option<&mut dyn RayObserver>,
) -> [Vec3; PACKET_WIDTH] {
    let samples = source.samples();
    let count = samples.count();
    if count == 1 {
        let (rays, mask) = source.primary_group(group);
        if let Some(strata) = source.draw_strata(group) {
            return shader.shade_strata(&rays, mask, &strata, counts, observer);
        }
        return shader.shade(&rays, mask, 0, counts, observer);
    }
    let side = samples.grid_side();
    if side == 0 {
        let mut sum = [Vec3::ZERO; PACKET_WIDTH];
        for index in 0..count {
            let (rays, mask) = source.sample_group(group, index);
            let watching: Option<&mut dyn RayObserver> = match observer {
                Some(ref mut o) => Some(&mut **o),
                None => None,
            };
            let colors = shader.shade(&rays, mask, 0, counts, watching);
            for (total, color) in sum.iter_mut().zip(colors) {
                *total += color;
            }
        }
        return sum.map(|total| total * (1.0 / count as f32));
    }
    // Packets go row by row, and their lanes too. Where the side divides
    // the group's width (4 and 16 sub-samples) a cell's strata rows lie
    // whole in one packet, so every cell meets its sub-samples in index
    // order and sums them as they come; otherwise they are kept, cell-major,
    // and summed in index order at the end.
    let side = i64::from(side);
    let in_order = i64::from(GROUP_WIDTH) % side == 0;
    let mut sum = [Vec3::ZERO; PACKET_WIDTH];
    let mut strata = if in_order {
        Vec::new()
    } else {
        vec![Vec3::ZERO; PACKET_WIDTH * count as usize]
    };
    let (gw, gh) = (i64::from(GROUP_WIDTH), i64::from(GROUP_HEIGHT));
    for packet_row in 0..side {
        for packet_col in 0..side {
            let packet = SampleGroup {
                col: group.col * side + packet_col * gw,
                row: group.row * side + packet_row * gh,
            };
            let (rays, mask) = source.strata_group(packet);
            let watching: Option<&mut dyn RayObserver> = match observer {
                Some(ref mut o) => Some(&mut **o),
                None => None,
            };
            let cells = PixelStrata::new(side as u32, packet.lane_samples());
            let colors = shader.shade_strata(&rays, mask, &cells, counts, watching);
            for (lane, color) in colors.into_iter().enumerate() {
                let lane = lane as i64;
                // The stratum's place in the group's block of strata.
                let (col, row) = (packet_col * gw + lane % gw, packet_row * gh + lane / gw);
                let ((cell_col, cell_row), index) = stratum_cell(col, row, side);
                let cell = (cell_row * gw + cell_col) as usize;
                if in_order {
                    sum[cell] += color;
                } else {
                    strata[cell * count as usize + index as usize] = color;
                }
            }
        }
    }
    let scale = 1.0 / count as f32;
    if in_order {
        return sum.map(|total| total * scale);
    }
    std::array::from_fn(|cell| {
        let colors = &strata[cell * count as usize..(cell + 1) * count as usize];
        box_filter(colors.iter().copied(), scale)
    })
}

/// A cell's colour from its sub-samples' in index order: the box filter
/// every path uses, so a cell resolved from kept strata equals a traced one
/// bit for bit.
pub fn box_filter(colors: impl IntoIterator<Item = Vec3>, scale: f32) -> Vec3 {
    let mut total = Vec3::ZERO;
    for color in colors {
        total += color;
    }
    total * scale
}

/// Traces `groups` in parallel; colours come back in the order given.
pub fn trace_groups(
    shader: &Shader,
    source: &dyn PrimaryRays,
    groups: &[SampleGroup],
) -> (Vec<[Vec3; PACKET_WIDTH]>, RayCounts) {
    trace_groups_observed(shader, source, groups, |_| None::<NoObserver>)
}

/// Never used as an observer: lets [`trace_groups`] share the observed path.
pub enum NoObserver {}

impl RayObserver for NoObserver {
    fn traced(
        &mut self,
        _: crate::shade::RayKind,
        _: &crate::ray::RayPacket,
        _: LaneMask,
        _: &[f32; PACKET_WIDTH],
    ) {
        match *self {}
    }
}

/// As [`trace_groups`], showing each group's rays to the observer
/// `observer_for(group)` makes (None: not observed).
pub fn trace_groups_observed<O: RayObserver>(
    shader: &Shader,
    source: &dyn PrimaryRays,
    groups: &[SampleGroup],
    observer_for: impl Fn(SampleGroup) -> Option<O> + Sync,
) -> (Vec<[Vec3; PACKET_WIDTH]>, RayCounts) {
    let (colors, counts) = trace_each(shader, groups, |&group| {
        (source, group, observer_for(group))
    });
    (
        colors,
        counts.into_iter().fold(RayCounts::default(), |a, b| a + b),
    )
}

/// Traces one group per item in parallel, each from the ray source, group
/// and observer `setup(item)` gives (one batch over groups of different
/// sources, such as several pyramid levels); each item's colours and rays
/// come back in the order given.
pub fn trace_each<'s, T: Sync, O: RayObserver>(
    shader: &Shader,
    items: &[T],
    setup: impl Fn(&T) -> (&'s dyn PrimaryRays, SampleGroup, Option<O>) + Sync,
) -> (Vec<[Vec3; PACKET_WIDTH]>, Vec<RayCounts>) {
    items
        .par_iter()
        .with_min_len(16)
        .map(|item| {
            let (source, group, mut observer) = setup(item);
            let mut counts = RayCounts::default();
            let colors = trace_group(
                shader,
                source,
                group,
                &mut counts,
                observer.as_mut().map(|o| o as &mut dyn RayObserver),
            );
            (colors, counts)
        })
        .unzip()
}

/// A linear-light RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Frame {
    pub fn new(width: u32, height: u32) -> Frame {
        Frame {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// 8-bit sRGB, clamped.
    pub fn to_rgb8(&self) -> image::RgbImage {
        let table = srgb_table();
        let mut out = image::RgbImage::new(self.width, self.height);
        out.par_chunks_exact_mut(3)
            .zip(self.pixels.par_iter())
            .for_each(|(dst, src)| dst.copy_from_slice(&src.to_array().map(|c| table.encode(c))));
        out
    }
}

/// The groups covering a whole `width` x `height` image.
pub fn image_groups(width: u32, height: u32) -> Vec<SampleGroup> {
    SampleGroup::covering(0..i64::from(width), 0..i64::from(height))
}

/// Renders the scene's camera view in full.
pub fn render_frame(scene: &Scene, intersector: &dyn Intersector) -> (Frame, RayCounts) {
    render_view(scene, &scene.camera, intersector)
}

/// Renders the scene through `camera` (which may differ from the scene's
/// own, e.g. posed by a timeline) in full, at the scene's samples a pixel.
pub fn render_view(
    scene: &Scene,
    camera: &Camera,
    intersector: &dyn Intersector,
) -> (Frame, RayCounts) {
    render_view_sampled(scene, camera, scene.samples, intersector)
}

/// As [`render_view`], `samples` a pixel.
pub fn render_view_sampled(
    scene: &Scene,
    camera: &Camera,
    samples: PixelSamples,
    intersector: &dyn Intersector,
) -> (Frame, RayCounts) {
    render_camera(&Shader::new(scene, intersector), camera, samples)
}

/// `camera`'s image traced in full through its own rays at `samples` a
/// pixel.
pub fn render_camera(
    shader: &Shader,
    camera: &Camera,
    samples: PixelSamples,
) -> (Frame, RayCounts) {
    let table = RayTable::with_samples(camera, samples);
    render_image(shader, &table, camera.width, camera.height)
}

/// Traces every pixel of a `width` x `height` image, pixel (x, y) from
/// `source`'s ray (x, y).
pub fn render_image(
    shader: &Shader,
    source: &dyn PrimaryRays,
    width: u32,
    height: u32,
) -> (Frame, RayCounts) {
    let mut frame = Frame::new(width, height);
    let width = width as usize;
    // Each band of GROUP_HEIGHT rows is written in place by the worker that
    // traces it: no per-frame list of groups or of their colours (at 640x480
    // those would be megabytes, fresh pages to fault in on every frame).
    let band = width * GROUP_HEIGHT as usize;
    let counts = frame
        .pixels
        .par_chunks_mut(band)
        .enumerate()
        .map(|(index, pixels)| {
            let row = (index * GROUP_HEIGHT as usize) as i64;
            let mut counts = RayCounts::default();
            let group_width = GROUP_WIDTH as usize;
            for x in (0..width).step_by(group_width) {
                let group = SampleGroup { col: x as i64, row };
                let colors = trace_group(shader, source, group, &mut counts, None);
                // Lanes run along rows of the group (`lane_samples`): each
                // row is one slice copy, cut at the image's right edge; the
                // band's last rows may be missing at its bottom edge.
                let n = group_width.min(width - x);
                for (y, lanes) in colors.chunks_exact(group_width).enumerate() {
                    let start = y * width + x;
                    if let Some(dst) = pixels.get_mut(start..start + n) {
                        dst.copy_from_slice(&lanes[..n]);
                    }
                }
            }
            counts
        })
        .reduce(RayCounts::default, |a, b| a + b);
    (frame, counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records the primary packets traced.
    struct Primaries(Vec<(RayPacket, LaneMask)>);

    impl RayObserver for Primaries {
        fn traced(
            &mut self,
            kind: crate::shade::RayKind,
            rays: &RayPacket,
            mask: LaneMask,
            _: &[f32; PACKET_WIDTH],
        ) {
            if kind == crate::shade::RayKind::Primary {
                self.0.push((*rays, mask));
            }
        }
    }

    #[test]
    fn square_counts_trace_packets_of_neighbouring_strata() {
        let scene = crate::scene::paper_scene(&crate::scene::SceneOverrides {
            width: Some(16),
            height: Some(8),
            ..Default::default()
        })
        .unwrap();
        let accel =
            crate::accel::Accelerator::build(crate::accel::BackendKind::Grid, &scene.objects)
                .unwrap();
        let shader = Shader::new(&scene, &accel);
        for (count, cells_a_packet) in [(4, 2), (16, 1)] {
            let samples = PixelSamples::new(count).unwrap();
            let table = RayTable::with_samples(&scene.camera, samples);
            let group = SampleGroup { col: 4, row: 2 };
            let mut seen = Primaries(Vec::new());
            let mut counts = RayCounts::default();
            let colors = trace_group(&shader, &table, group, &mut counts, Some(&mut seen));
            assert_eq!(
                seen.0.len(),
                count as usize,
                "{count}: one packet per 8 rays"
            );
            // Which cell each ray of a packet is a sub-sample of.
            let cell_of = |ray: &Ray| {
                group.lane_samples().into_iter().position(|(col, row)| {
                    (0..count).any(|k| table.sample(col, row, k).unwrap().dir == ray.dir)
                })
            };
            for (rays, mask) in &seen.0 {
                assert_eq!(*mask, 0xff);
                let mut cells: Vec<_> = rays.iter().map(|r| cell_of(r).unwrap()).collect();
                cells.sort_unstable();
                cells.dedup();
                assert_eq!(cells.len(), cells_a_packet, "{count}: cells {cells:?}");
            }
            // And a cell is still the box filter of its sub-samples.
            let strata = Strata::new(&table);
            let side = i64::from(strata.side());
            for (lane, (col, row)) in group.lane_samples().into_iter().enumerate() {
                let sub: Vec<Vec3> = (0..count as i64)
                    .map(|k| {
                        let stratum = (col * side + k % side, row * side + k / side);
                        let g = SampleGroup::containing(stratum.0, stratum.1);
                        let colors = trace_group(&shader, &strata, g, &mut counts, None);
                        colors[((stratum.1 - g.row) * 4 + stratum.0 - g.col) as usize]
                    })
                    .collect();
                assert_eq!(colors[lane], box_filter(sub, 1.0 / count as f32));
            }
        }
    }

    #[test]
    fn groups_align_and_cover() {
        assert_eq!(
            SampleGroup::containing(5, 3),
            SampleGroup { col: 4, row: 2 }
        );
        assert_eq!(
            SampleGroup::containing(-1, -1),
            SampleGroup { col: -4, row: -2 }
        );
        let groups = SampleGroup::covering(3..9, 1..4);
        let mut covered = std::collections::HashSet::new();
        for g in &groups {
            assert_eq!(g.col % 4, 0);
            assert_eq!(g.row % 2, 0);
            covered.extend(g.lane_samples());
        }
        for col in 3..9 {
            for row in 1..4 {
                assert!(covered.contains(&(col, row)));
            }
        }
        assert_eq!(groups.len(), 3 * 2);
        assert_eq!(image_groups(640, 480).len(), 160 * 240);
    }
}
