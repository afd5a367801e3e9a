//! OBJ faces of more than three vertices as triangles, cut in the face's
//! own plane so that a concave face (an L, or a ring whose outline runs in
//! and back out along a slit) keeps its notches and holes open.
//!
//! Promises: a convex face is cut as a fan from its first vertex, exactly
//! as tobj cut every face (so models of convex faces render as before); a
//! concave one is ear-clipped in the plane that best fits it (Newell's
//! normal, so a slightly non-planar face works too); every triangle winds
//! as the face does. A face whose edges cross each other has no inside to
//! cut: it is fanned as before, and a warning names the line of the first
//! such face and how many there are.

use std::path::Path;

use glam::{DVec2, DVec3, Vec3};

/// Cuts the faces of a file's models into triangles, in the file's order,
/// and remembers which lines held faces it could not cut in their plane.
pub(super) struct FaceCutter {
    /// The line of each face in the file, in order.
    lines: Vec<usize>,
    /// Faces cut so far.
    done: usize,
    triangulator: Triangulator,
    self_intersecting: Vec<usize>,
    no_area: Vec<usize>,
    too_large: Vec<usize>,
}

impl FaceCutter {
    pub(super) fn new(text: &str) -> Self {
        let lines = text
            .lines()
            .enumerate()
            .filter(|(_, line)| line.split_whitespace().next() == Some("f"))
            .map(|(number, _)| number + 1)
            .collect();
        Self {
            lines,
            done: 0,
            triangulator: Triangulator::default(),
            self_intersecting: Vec::new(),
            no_area: Vec::new(),
            too_large: Vec::new(),
        }
    }

    /// The triangles of a model's faces: `indices` holds each face's
    /// vertices in turn, `arities` their counts (empty when all are
    /// triangles).
    pub(super) fn cut(
        &mut self,
        positions: &[Vec3],
        indices: &[u32],
        arities: &[u32],
    ) -> Vec<[u32; 3]> {
        let mut triangles = Vec::with_capacity(indices.len() / 3);
        let all_triangles = vec![
            3;
            if arities.is_empty() {
                indices.len() / 3
            } else {
                0
            }
        ];
        let arities = if arities.is_empty() {
            &all_triangles
        } else {
            arities
        };
        let mut rest = indices;
        for &arity in arities {
            let (face, after) = rest.split_at((arity as usize).min(rest.len()));
            rest = after;
            let line = self.lines.get(self.done).copied();
            self.done += 1;
            let problem = self
                .triangulator
                .triangulate(positions, face, &mut triangles);
            let at = match problem {
                Ok(()) => continue,
                Err(FaceProblem::SelfIntersecting) => &mut self.self_intersecting,
                Err(FaceProblem::NoArea) => &mut self.no_area,
                Err(FaceProblem::TooLarge) => &mut self.too_large,
            };
            at.extend(line);
        }
        triangles
    }

    /// A warning for each kind of face that could not be cut, naming the
    /// first one's line.
    pub(super) fn warnings(&self, path: &Path) -> Vec<String> {
        let warn = |lines: &[usize], why: &str| {
            lines.first().map(|line| {
                format!(
                    "{}:{line}: f: {why}: it cannot be cut into triangles in its plane, \
                     and is filled as a fan from its first vertex ({} such face(s) in the file)",
                    path.display(),
                    lines.len()
                )
            })
        };
        [
            warn(
                &self.self_intersecting,
                "the face's edges cross each other, or it goes round more than once",
            ),
            warn(&self.no_area, "the face encloses no area"),
            warn(
                &self.too_large,
                &format!("the face is concave, with more than {MAX_CUT_CORNERS} corners"),
            ),
        ]
        .into_iter()
        .flatten()
        .collect()
    }
}

/// Why a face could not be cut in its plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FaceProblem {
    /// Two of its edges cross (a bow-tie), or it goes round more than once.
    SelfIntersecting,
    /// Concave, with more than [`MAX_CUT_CORNERS`] corners.
    TooLarge,
    /// It encloses no area in any plane, though not all its corners lie on
    /// one line (it doubles back on itself).
    NoArea,
}

/// Turns at a corner closer than this to straight on (radians) count as
/// straight, so that float noise on a vertex in the middle of an edge
/// does not make a convex face concave.
const STRAIGHT: f64 = 1e-6;

/// Orientations smaller than this, relative to the lengths involved,
/// count as collinear: edges that touch or overlap (a ring's slit runs
/// both ways along one line) do not cross.
const COLLINEAR: f64 = 1e-9;

/// Corners of the largest concave face cut in its plane. Ear clipping
/// takes time growing with the square of the corners (a tenth of a second
/// here, minutes at 300,000): a larger face is filled as a fan, with a
/// warning.
pub(super) const MAX_CUT_CORNERS: usize = 10_000;

/// Cuts faces into triangles, keeping its buffers from face to face.
#[derive(Default)]
struct Triangulator {
    ears: earcut::Earcut<f64>,
    flat: Vec<DVec2>,
    cut: Vec<u32>,
}

impl Triangulator {
    /// Appends the triangles of `face` (indices into `positions`, in the
    /// file's order) to `out`. On a problem the face is still appended, as
    /// a fan from its first vertex.
    fn triangulate(
        &mut self,
        positions: &[Vec3],
        face: &[u32],
        out: &mut Vec<[u32; 3]>,
    ) -> Result<(), FaceProblem> {
        let fan = |out: &mut Vec<[u32; 3]>| {
            out.extend(face.windows(2).skip(1).map(|w| [face[0], w[0], w[1]]));
        };
        if face.len() <= 3 {
            fan(out);
            return Ok(());
        }
        let corners: Vec<DVec3> = face
            .iter()
            .map(|&i| positions[i as usize].as_dvec3())
            .collect();
        let Some(normal) = plane_normal(&corners) else {
            // All on one line: the fan's triangles have no area, and are
            // dropped and counted with the other degenerate ones.
            fan(out);
            return Ok(());
        };
        let (u, v) = normal.any_orthonormal_pair();
        // (u, v, normal) is right-handed: the face runs counter-clockwise
        // in the plane when it winds about its normal.
        let (u, v) = if u.cross(v).dot(normal) > 0.0 {
            (u, v)
        } else {
            (v, u)
        };
        self.flat.clear();
        self.flat.extend(corners.iter().map(|&p| {
            let d = p - corners[0];
            DVec2::new(d.dot(u), d.dot(v))
        }));
        if is_convex(&self.flat) {
            fan(out);
            return Ok(());
        }
        if face.len() > MAX_CUT_CORNERS {
            fan(out);
            return Err(FaceProblem::TooLarge);
        }
        if edges_cross(&self.flat) || runs_over_itself(&self.flat) {
            fan(out);
            return Err(FaceProblem::SelfIntersecting);
        }
        self.ears.earcut(
            self.flat.iter().map(|p| p.to_array()),
            &[] as &[u32],
            &mut self.cut,
        );
        if self.cut.is_empty() {
            fan(out);
            return Err(FaceProblem::NoArea);
        }
        for t in self.cut.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
            let [pa, pb, pc] = [a, b, c].map(|i| self.flat[i]);
            // The ear clipper winds its own way; the face's winding is what
            // the normals are made from.
            if (pb - pa).perp_dot(pc - pa) >= 0.0 {
                out.push([face[a], face[b], face[c]]);
            } else {
                out.push([face[a], face[c], face[b]]);
            }
        }
        Ok(())
    }
}

/// The unit normal of the plane that best fits `corners` (Newell's, which
/// winds with the face); for a face whose parts wind opposite ways and
/// cancel out (a symmetric bow-tie), that of its largest corner. `None`
/// when all corners lie on one line.
fn plane_normal(corners: &[DVec3]) -> Option<DVec3> {
    let origin = corners[0];
    let relative = |p: DVec3| p - origin;
    let extent = corners
        .iter()
        .map(|&p| relative(p).length_squared())
        .fold(0.0, f64::max);
    let tiny = extent * 1e-12;
    let newell: DVec3 = corners
        .iter()
        .zip(corners.iter().cycle().skip(1))
        .map(|(&a, &b)| relative(a).cross(relative(b)))
        .sum();
    if newell.length() > tiny {
        return Some(newell.normalize());
    }
    let largest = corners
        .windows(2)
        .map(|w| relative(w[0]).cross(relative(w[1])))
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
    (largest.length() > tiny).then(|| largest.normalize())
}

/// Whether the counter-clockwise polygon `flat` turns left (or runs
/// straight on) at every corner, and goes round once: the fan from any
/// corner then covers exactly it.
fn is_convex(flat: &[DVec2]) -> bool {
    let mut corners: Vec<DVec2> = Vec::with_capacity(flat.len());
    for &p in flat {
        if corners.last() != Some(&p) {
            corners.push(p);
        }
    }
    while corners.len() > 1 && corners.first() == corners.last() {
        corners.pop();
    }
    if corners.len() < 3 {
        return false;
    }
    let n = corners.len();
    let mut total = 0.0;
    for i in 0..n {
        let incoming = corners[i] - corners[(i + n - 1) % n];
        let outgoing = corners[(i + 1) % n] - corners[i];
        let turn = incoming.perp_dot(outgoing).atan2(incoming.dot(outgoing));
        if !(-STRAIGHT..=std::f64::consts::PI - STRAIGHT).contains(&turn) {
            return false;
        }
        total += turn;
    }
    // A star drawn in one stroke turns left throughout, but twice round.
    (total - std::f64::consts::TAU).abs() < 1.0
}

/// Whether two edges of the closed polygon `flat` cross each other at a
/// point inside both. Edges that meet at a corner, touch or run along one
/// another (as a slit into a ring does, out and back) do not count.
fn edges_cross(flat: &[DVec2]) -> bool {
    let by_x = |p: &DVec2, q: &DVec2| p.x.total_cmp(&q.x).then(p.y.total_cmp(&q.y));
    // Each edge once, from its end of least x: a face that goes round the
    // same outline many times has only that outline's edges to test.
    let mut edges: Vec<(DVec2, DVec2)> = flat
        .iter()
        .zip(flat.iter().cycle().skip(1))
        .filter(|(a, b)| a != b)
        .map(|(&a, &b)| if by_x(&a, &b).is_le() { (a, b) } else { (b, a) })
        .collect();
    edges.sort_by(|e, f| by_x(&e.0, &f.0).then(by_x(&e.1, &f.1)));
    edges.dedup();
    // Swept along x: an edge is only tested against those whose x ranges
    // overlap its own.
    for (k, &edge) in edges.iter().enumerate() {
        for &other in &edges[k + 1..] {
            if other.0.x > edge.1.x {
                break;
            }
            if cross_properly(edge, other) {
                return true;
            }
        }
    }
    false
}

/// Whether the polygon `flat` passes through one point more than twice: a
/// slit into a ring passes its ends twice, a face that goes round its
/// outline again more often (and the ear clipper slows to minutes on it).
fn runs_over_itself(flat: &[DVec2]) -> bool {
    let mut points = flat.to_vec();
    points.sort_by(|p, q| p.x.total_cmp(&q.x).then(p.y.total_cmp(&q.y)));
    points.windows(3).any(|w| w[0] == w[1] && w[1] == w[2])
}

/// Whether segments `(a, b)` and `(c, d)` cross at a single point inside
/// both (each one's ends strictly either side of the other's line).
fn cross_properly((a, b): (DVec2, DVec2), (c, d): (DVec2, DVec2)) -> bool {
    let side = |from: DVec2, to: DVec2, p: DVec2| {
        let along = to - from;
        let toward = p - from;
        let orientation = along.perp_dot(toward);
        if orientation.abs() <= COLLINEAR * along.length() * toward.length() {
            0.0
        } else {
            orientation.signum()
        }
    };
    side(a, b, c) * side(a, b, d) < 0.0 && side(c, d, a) * side(c, d, b) < 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(points: &[[f32; 3]], face: &[u32]) -> (Vec<[u32; 3]>, Result<(), FaceProblem>) {
        let positions: Vec<Vec3> = points.iter().map(|&p| Vec3::from_array(p)).collect();
        let mut out = Vec::new();
        let result = Triangulator::default().triangulate(&positions, face, &mut out);
        (out, result)
    }

    /// Twice the area of each triangle along `normal` (negative when it
    /// winds the other way).
    fn areas(points: &[[f32; 3]], triangles: &[[u32; 3]], normal: Vec3) -> Vec<f32> {
        let p = |i: u32| Vec3::from_array(points[i as usize]);
        triangles
            .iter()
            .map(|&[a, b, c]| (p(b) - p(a)).cross(p(c) - p(a)).dot(normal))
            .collect()
    }

    #[test]
    fn a_convex_face_is_the_fan_from_its_first_vertex() {
        // A square with a vertex in the middle of an edge, slightly bent
        // out of its plane.
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 2.0, 0.05],
            [0.0, 2.0, 0.0],
        ];
        let (triangles, result) = cut(&points, &[1, 2, 3, 4, 0]);
        assert_eq!(result, Ok(()));
        assert_eq!(triangles, [[1, 2, 3], [1, 3, 4], [1, 4, 0]]);
    }

    #[test]
    fn an_l_is_cut_without_filling_its_notch() {
        // Counter-clockwise seen from +z, from a corner that cannot see the
        // whole L: its fan covers part of the notch x > 1, y > 1.
        let points = [
            [2.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
        ];
        let (triangles, result) = cut(&points, &[0, 1, 2, 3, 4, 5]);
        assert_eq!(result, Ok(()));
        assert_eq!(triangles.len(), 4);
        let areas = areas(&points, &triangles, Vec3::Z);
        assert!(areas.iter().all(|&a| a > 0.0), "{areas:?}");
        assert!((areas.iter().sum::<f32>() - 6.0).abs() < 1e-5, "{areas:?}");
        let in_notch = |&[a, b, c]: &[u32; 3]| {
            let centre = [a, b, c]
                .map(|i| Vec3::from_array(points[i as usize]))
                .iter()
                .sum::<Vec3>()
                / 3.0;
            centre.x > 1.0 && centre.y > 1.0
        };
        assert!(!triangles.iter().any(in_notch), "{triangles:?}");
    }

    #[test]
    fn a_ring_through_a_slit_keeps_its_hole_and_winds_as_the_face() {
        // A 4x4 square with a 2x2 hole, clockwise seen from +z: round the
        // outside, in along the slit, round the hole the other way, out.
        let points = [
            [0.0, 0.0, 0.0],
            [0.0, 4.0, 0.0],
            [4.0, 4.0, 0.0],
            [4.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [3.0, 1.0, 0.0],
            [3.0, 3.0, 0.0],
            [1.0, 3.0, 0.0],
        ];
        let (triangles, result) = cut(&points, &[0, 1, 2, 3, 0, 4, 5, 6, 7, 4]);
        assert_eq!(result, Ok(()));
        let areas = areas(&points, &triangles, -Vec3::Z);
        assert!(areas.iter().all(|&a| a > 0.0), "{areas:?}");
        assert!(
            (areas.iter().sum::<f32>() - 2.0 * 12.0).abs() < 1e-4,
            "{areas:?}"
        );
    }

    #[test]
    fn a_bow_tie_is_fanned_and_reported() {
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let (triangles, result) = cut(&points, &[0, 1, 2, 3]);
        assert_eq!(result, Err(FaceProblem::SelfIntersecting));
        assert_eq!(triangles, [[0, 1, 2], [0, 2, 3]]);
        // Lopsided, so that its halves do not cancel out.
        let points = [
            [0.0, 0.0, 0.0],
            [3.0, 2.0, 0.0],
            [3.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert_eq!(
            cut(&points, &[0, 1, 2, 3]).1,
            Err(FaceProblem::SelfIntersecting)
        );
    }

    #[test]
    fn a_face_that_doubles_back_is_fanned_and_reported() {
        let points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        let (triangles, result) = cut(&points, &[0, 1, 2, 1]);
        assert_eq!(result, Err(FaceProblem::NoArea));
        assert_eq!(triangles, [[0, 1, 2], [0, 2, 1]]);
    }

    #[test]
    fn a_face_round_one_triangle_again_and_again_is_reported_at_once() {
        // As a fuzzed megabyte line `f 1 2 3 1 2 3 ...` is; the ear clipper
        // took seconds on a thousand rounds.
        let points = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let face: Vec<u32> = (0..3000).map(|i| i % 3).collect();
        let (triangles, result) = cut(&points, &face);
        assert_eq!(result, Err(FaceProblem::SelfIntersecting));
        assert_eq!(triangles.len(), 2998);
    }

    #[test]
    fn a_concave_face_of_too_many_corners_is_fanned_and_reported() {
        // A star: every other corner pulled in.
        let star = |n: usize| -> Vec<[f32; 3]> {
            (0..n)
                .map(|i| {
                    let angle = i as f32 / n as f32 * std::f32::consts::TAU;
                    let r = if i % 2 == 0 { 1.0 } else { 0.5 };
                    [r * angle.cos(), r * angle.sin(), 0.0]
                })
                .collect()
        };
        for (n, wanted) in [
            (MAX_CUT_CORNERS, Ok(())),
            (MAX_CUT_CORNERS + 2, Err(FaceProblem::TooLarge)),
        ] {
            let face: Vec<u32> = (0..n as u32).collect();
            let (triangles, result) = cut(&star(n), &face);
            assert_eq!((triangles.len(), result), (n - 2, wanted));
        }
    }

    #[test]
    fn a_face_on_one_line_is_left_to_the_degenerate_count() {
        let points = [
            [0.0, 0.0, 0.0],
            [1.0, 1.0, 1.0],
            [2.0, 2.0, 2.0],
            [3.0, 3.0, 3.0],
        ];
        let (triangles, result) = cut(&points, &[0, 1, 2, 3]);
        assert_eq!(result, Ok(()));
        assert_eq!(triangles.len(), 2);
    }
}
