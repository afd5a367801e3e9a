//! PNG charts for `bench` and `tradeoff`: line charts (per-frame series) and
//! labelled scatter charts (error against speedup).
//!
//! Text is drawn with a font embedded in the binary (DejaVu Sans, licence in
//! `src/plot/LICENSE-DejaVu.txt`) through plotters' `ab_glyph` backend, so a
//! chart renders the same on a fresh machine with no fontconfig or freetype.
//! Charts are drawn into memory and written through [`crate::output`], so a
//! chart file appears only when complete.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::output::{self, OutputError};

/// Every chart is this size in pixels: large enough for a legend beside a
/// hundred-frame series, small enough to sit in a report.
pub const CHART_SIZE: (u32, u32) = (960, 600);

const FONT_FAMILY: &str = "sans-serif";
const FONT_BYTES: &[u8] = include_bytes!("plot/DejaVuSans.ttf");

/// Colours told apart by most readers, including the colour-blind (Tableau 10).
const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// The colour (RGB) of the `index`th series or group, as charts draw it.
pub fn series_color(index: usize) -> [u8; 3] {
    let RGBColor(r, g, b) = palette_color(index);
    [r, g, b]
}

fn palette_color(index: usize) -> RGBColor {
    PALETTE[index % PALETTE.len()]
}

/// A named line: `points` are (x, y) in drawing order.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// One point of a scatter chart, with the text written beside it.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledPoint {
    pub x: f64,
    pub y: f64,
    pub label: String,
}

/// Points of one colour in a scatter chart; `label` names them in the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct ScatterGroup {
    pub label: String,
    pub points: Vec<LabelledPoint>,
}

#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{path}: cannot draw chart: {message}")]
    Draw { path: PathBuf, message: String },
    #[error("cannot load the embedded plot font")]
    Font,
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// Draws `series` as lines on one pair of axes and writes the PNG to `path`.
/// Points with a non-finite coordinate are left out (a frame with no
/// measurement must not wreck the axes).
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<(), PlotError> {
    let finite: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| s.points.iter().copied().filter(is_finite).collect())
        .collect();
    let (x_range, y_range) = axis_ranges(finite.iter().flatten().copied(), series.len());
    draw_png(path, |root| {
        let mut chart = cartesian(root, title, x_label, y_label, x_range, y_range)?;
        for (index, (series, points)) in series.iter().zip(finite).enumerate() {
            let color = palette_color(index);
            chart
                .draw_series(LineSeries::new(points, color.stroke_width(2)))?
                .label(series.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        draw_legend(&mut chart, series.len())
    })
}

/// Draws each group's points as dots in its own colour, each point's label
/// beside it, and writes the PNG to `path`. Non-finite points are left out.
pub fn scatter_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    groups: &[ScatterGroup],
) -> Result<(), PlotError> {
    let finite: Vec<Vec<&LabelledPoint>> = groups
        .iter()
        .map(|g| g.points.iter().filter(|p| is_finite(&(p.x, p.y))).collect())
        .collect();
    let (x_range, y_range) = axis_ranges(finite.iter().flatten().map(|p| (p.x, p.y)), groups.len());
    draw_png(path, |root| {
        let mut chart = cartesian(root, title, x_label, y_label, x_range, y_range)?;
        let mut labels = Vec::new();
        for (index, (group, points)) in groups.iter().zip(finite).enumerate() {
            let color = palette_color(index);
            chart
                .draw_series(
                    points
                        .iter()
                        .map(|p| Circle::new((p.x, p.y), DOT_RADIUS, color.filled())),
                )?
                .label(group.label.as_str())
                .legend(move |(x, y)| Circle::new((x + 10, y), DOT_RADIUS, color.filled()));
            for point in points {
                let at = chart.backend_coord(&(point.x, point.y));
                labels.push((at, point.label.as_str(), color));
            }
        }
        let plot_area = chart.plotting_area().get_pixel_range();
        draw_point_labels(root, plot_area, &labels)?;
        draw_legend(&mut chart, groups.len())
    })
}

const DOT_RADIUS: i32 = 5;

/// Pixel rectangle: left, top, right, bottom.
type PixelRect = (i32, i32, i32, i32);

/// Whether two rectangles come closer than a few pixels (text estimates
/// are not exact, and touching labels read as one).
fn overlaps(a: &PixelRect, b: &PixelRect) -> bool {
    const CLEARANCE: i32 = 4;
    a.0 < b.2 + CLEARANCE && b.0 < a.2 + CLEARANCE && a.1 < b.3 + CLEARANCE && b.1 < a.3 + CLEARANCE
}

/// Writes each label beside its dot, at the first of a few places around
/// it that stays inside the plotting area and clear of every dot and
/// label already placed (settings often land close together, e.g. exact
/// ones all at zero error).
fn draw_point_labels<'b>(
    root: &DrawingArea<BitMapBackend<'b>, Shift>,
    (x_range, y_range): (Range<i32>, Range<i32>),
    labels: &[((i32, i32), &str, RGBColor)],
) -> DrawResult<(), BitMapBackend<'b>> {
    let font = (FONT_FAMILY, 13).into_font();
    // The dots first, in the order of `labels`; placed labels follow.
    let mut taken: Vec<PixelRect> = labels
        .iter()
        .map(|&((x, y), _, _)| {
            let r = DOT_RADIUS + 1;
            (x - r, y - r, x + r, y + r)
        })
        .collect();
    for (own_dot, &((x, y), text, color)) in labels.iter().enumerate() {
        if text.is_empty() {
            continue;
        }
        let style = font.clone().color(&color);
        let (w, h) = root.estimate_text_size(text, &style)?;
        let (w, h) = (w as i32, h as i32);
        let gap = DOT_RADIUS + 3;
        let mut candidates = vec![
            (x + gap, y - h - 2),
            (x + gap, y + 2),
            (x - gap - w, y - h - 2),
            (x - gap - w, y + 2),
            (x - w / 2, y - h - gap),
            (x - w / 2, y + gap),
        ];
        // Farther out, above and below in steps of a line, on either side:
        // these get a leader line back to their dot.
        let near = candidates.len();
        for step in 1..12 {
            let dy = step * (h + 4);
            for left in [x + gap, x - gap - w] {
                candidates.push((left, y - h - 2 - dy));
                candidates.push((left, y + 2 + dy));
            }
        }
        let rect = |(left, top): (i32, i32)| (left, top, left + w, top + h);
        let inside = |r: &PixelRect| {
            r.0 >= x_range.start && r.2 <= x_range.end && r.1 >= y_range.start && r.3 <= y_range.end
        };
        let (index, place) = candidates
            .iter()
            .map(|&c| rect(c))
            .enumerate()
            .find(|(_, r)| {
                let clear = taken
                    .iter()
                    .enumerate()
                    .all(|(i, t)| i == own_dot || !overlaps(r, t));
                inside(r) && clear
            })
            .or_else(|| {
                candidates
                    .iter()
                    .map(|&c| rect(c))
                    .enumerate()
                    .find(|(_, r)| inside(r))
            })
            .unwrap_or_else(|| (0, rect(candidates[0])));
        if index >= near {
            let anchor_x = if place.0 > x { place.0 } else { place.2 };
            let anchor_y = (place.1 + place.3) / 2;
            root.draw(&PathElement::new(
                vec![(x, y), (anchor_x, anchor_y)],
                color.mix(0.6).stroke_width(1),
            ))?;
        }
        root.draw(&Text::new(text.to_string(), (place.0, place.1), style))?;
        taken.push(place);
    }
    Ok(())
}

type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

fn cartesian<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    x_range: Range<f64>,
    y_range: Range<f64>,
) -> DrawResult<Chart<'a, 'b>, BitMapBackend<'b>> {
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT_FAMILY, 24))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x_range, y_range)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT_FAMILY, 14))
        .axis_desc_style((FONT_FAMILY, 16))
        .x_label_formatter(&|x| tick_label(*x))
        .y_label_formatter(&|y| tick_label(*y))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    Ok(chart)
}

/// Draws the legend box, unless there is nothing to name.
fn draw_legend<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    entries: usize,
) -> DrawResult<(), BitMapBackend<'b>> {
    if entries == 0 {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT_FAMILY, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
}

/// Runs `draw` on a white in-memory canvas of [`CHART_SIZE`] and saves it.
fn draw_png(
    path: &Path,
    draw: impl for<'b> FnOnce(
        &DrawingArea<BitMapBackend<'b>, Shift>,
    ) -> DrawResult<(), BitMapBackend<'b>>,
) -> Result<(), PlotError> {
    register_font()?;
    let (width, height) = CHART_SIZE;
    let mut pixels = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, CHART_SIZE).into_drawing_area();
        let drawn = root
            .fill(&WHITE)
            .and_then(|()| draw(&root))
            .and_then(|()| root.present());
        drawn.map_err(|error| PlotError::Draw {
            path: path.to_path_buf(),
            message: error.to_string(),
        })?;
    }
    let image = image::RgbImage::from_raw(width, height, pixels)
        .expect("the canvas buffer holds exactly width * height RGB pixels");
    output::save_image(path, &image)?;
    Ok(())
}

/// Registers the embedded font with plotters once per process; plotters
/// keeps fonts in a global table, so later charts find it by family name.
fn register_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    ok.then_some(()).ok_or(PlotError::Font)
}

fn is_finite(&(x, y): &(f64, f64)) -> bool {
    x.is_finite() && y.is_finite()
}

/// Tick text without noise: `10` rather than `10.0`, at most three
/// significant decimals otherwise.
fn tick_label(value: f64) -> String {
    if value == value.round() && value.abs() < 1e15 {
        format!("{value:.0}")
    } else {
        let text = format!("{value:.3}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Height of the legend box, in pixels, for `entries` lines at the legend font.
fn legend_height(entries: usize) -> f64 {
    if entries == 0 {
        0.0
    } else {
        22.0 * entries as f64 + 16.0
    }
}

/// Axis ranges that hold every point with a margin, and room above the
/// data for a legend of `legend_entries` lines so it hides no point. The y
/// axis starts at zero when no value is negative, so heights compare at a
/// glance (times, ray counts and errors are all non-negative); an empty or
/// flat range is widened so the axes can still be drawn.
fn axis_ranges(
    points: impl Iterator<Item = (f64, f64)>,
    legend_entries: usize,
) -> (Range<f64>, Range<f64>) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for (px, py) in points {
        x = (x.0.min(px), x.1.max(px));
        y = (y.0.min(py), y.1.max(py));
    }
    if y.0 >= 0.0 {
        y.0 = 0.0;
    }
    let y_range = padded(y);
    // The plotting area is the chart less caption, margins and the x labels.
    let plot_height = f64::from(CHART_SIZE.1) - 130.0;
    let reserve = (legend_height(legend_entries) / plot_height).min(0.6);
    let span = y_range.end - y_range.start;
    let y_range = y_range.start..y_range.start + span / (1.0 - reserve);
    (padded(x), y_range)
}

fn padded((low, high): (f64, f64)) -> Range<f64> {
    if low > high {
        return 0.0..1.0;
    }
    let span = high - low;
    let pad = if span > 0.0 {
        span * 0.08
    } else {
        low.abs().max(1.0) * 0.5
    };
    let low_pad = if low == 0.0 { 0.0 } else { pad };
    (low - low_pad)..(high + pad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decoded(path: &Path) -> image::RgbImage {
        image::open(path).unwrap().to_rgb8()
    }

    fn pixels_of(image: &image::RgbImage, color: [u8; 3]) -> usize {
        image.pixels().filter(|p| p.0 == color).count()
    }

    fn non_white_share(image: &image::RgbImage) -> f64 {
        let non_white = image.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        non_white as f64 / (image.width() * image.height()) as f64
    }

    #[test]
    fn line_chart_draws_each_series_in_its_colour() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lines.png");
        let series = [
            Series {
                label: "full".into(),
                points: (0..100)
                    .map(|i| (i as f64, 30.0 + (i % 7) as f64))
                    .collect(),
            },
            Series {
                label: "accelerated".into(),
                points: (0..100).map(|i| (i as f64, 2.0 + (i % 3) as f64)).collect(),
            },
        ];
        line_chart(&path, "ms per frame", "frame", "ms", &series).unwrap();
        let image = decoded(&path);
        assert_eq!(image.dimensions(), CHART_SIZE);
        assert!(pixels_of(&image, series_color(0)) > 500);
        assert!(pixels_of(&image, series_color(1)) > 500);
        let share = non_white_share(&image);
        assert!(share > 0.01 && share < 0.5, "non-white share {share}");
        // Only the chart itself: no temporary file left beside it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn scatter_chart_draws_points_and_their_labels() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scatter.png");
        let group = |label: &str, points: &[(f64, f64, &str)]| ScatterGroup {
            label: label.into(),
            points: points
                .iter()
                .map(|&(x, y, label)| LabelledPoint {
                    x,
                    y,
                    label: label.into(),
                })
                .collect(),
        };
        let groups = [
            group("filter", &[(9.0, 1.5, "nearest"), (8.0, 0.7, "bilinear")]),
            group(
                "regions",
                &[
                    (3.0, 0.0, "8"),
                    (4.0, 0.0, "16"),
                    (f64::NAN, 1.0, "skipped"),
                ],
            ),
        ];
        scatter_chart(
            &path,
            "error vs speedup",
            "speedup",
            "mean abs error",
            &groups,
        )
        .unwrap();
        let with_labels = decoded(&path);
        assert_eq!(with_labels.dimensions(), CHART_SIZE);
        // A filled dot of radius 5 covers ~70 pixels; the legend adds one per group.
        assert!(pixels_of(&with_labels, series_color(0)) > 3 * 60);
        assert!(pixels_of(&with_labels, series_color(1)) > 3 * 60);

        // The point labels are drawn: the same chart without them has fewer
        // coloured pixels (text is anti-aliased, so count non-white ones).
        let unlabelled: Vec<ScatterGroup> = groups
            .iter()
            .map(|g| ScatterGroup {
                label: g.label.clone(),
                points: g
                    .points
                    .iter()
                    .map(|p| LabelledPoint {
                        label: String::new(),
                        ..p.clone()
                    })
                    .collect(),
            })
            .collect();
        let bare_path = dir.path().join("bare.png");
        scatter_chart(
            &bare_path,
            "error vs speedup",
            "speedup",
            "mean abs error",
            &unlabelled,
        )
        .unwrap();
        assert!(non_white_share(&with_labels) > non_white_share(&decoded(&bare_path)));
    }

    #[test]
    fn empty_and_flat_data_still_draw_axes() {
        let dir = tempfile::tempdir().unwrap();
        let empty = dir.path().join("empty.png");
        line_chart(&empty, "nothing", "x", "y", &[]).unwrap();
        assert!(non_white_share(&decoded(&empty)) > 0.005);
        let flat = dir.path().join("flat.png");
        let series = [Series {
            label: "one".into(),
            points: vec![(5.0, 2.0), (5.0, 2.0)],
        }];
        line_chart(&flat, "flat", "x", "y", &series).unwrap();
        assert_eq!(decoded(&flat).dimensions(), CHART_SIZE);
    }

    #[test]
    fn unwritable_path_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no-such-dir").join("chart.png");
        let error = line_chart(&path, "t", "x", "y", &[]).unwrap_err();
        assert!(error.to_string().contains("chart.png"), "{error}");
        assert!(!path.exists());
    }

    #[test]
    fn ranges_start_at_zero_for_non_negative_data_and_widen_flat_ones() {
        let (x, y) = axis_ranges([(2.0, 3.0), (4.0, 5.0)].into_iter(), 0);
        assert!(x.start < 2.0 && x.end > 4.0);
        assert_eq!(y.start, 0.0);
        assert!(y.end > 5.0);
        let (x, y) = axis_ranges([(1.0, -1.0)].into_iter(), 0);
        assert!(x.start < 1.0 && x.end > 1.0);
        assert!(y.start < -1.0 && y.end > -1.0);
        assert_eq!(axis_ranges(std::iter::empty(), 0), (0.0..1.0, 0.0..1.0));
        // A legend gets room above the highest point.
        let (_, bare) = axis_ranges([(0.0, 10.0)].into_iter(), 0);
        let (_, with_legend) = axis_ranges([(0.0, 10.0)].into_iter(), 4);
        assert_eq!(bare.start, with_legend.start);
        let room = (with_legend.end - 10.0) / (with_legend.end - with_legend.start);
        let needed = legend_height(4) / (f64::from(CHART_SIZE.1) - 130.0);
        assert!(room >= needed, "room {room} for a legend needing {needed}");
    }
}
