//! Shading normals as a model's author meant them, and where shadow rays
//! leave a smooth-shaded triangle.
//!
//! Promises: a mesh whose file gives no normals is smoothed only across
//! edges whose faces meet at less than the crease angle (an angle of 0
//! leaves every triangle flat); vertices are split where a crease runs
//! through them, and only there, so a mesh without creases keeps its
//! vertices and their order. The shadow-ray origin of a smooth triangle is
//! a pure function of the triangle and the hit's barycentrics.

use std::collections::HashMap;

use glam::Vec3;

use super::TriangleMesh;

/// The crease angle, in degrees, for meshes whose file has no normals and
/// whose scene says nothing: smooth across the shallow edges of a curved
/// surface's tessellation, sharp at a box's 90-degree edges.
pub const DEFAULT_CREASE_ANGLE_DEG: f32 = 30.0;

/// Gives `mesh` vertex normals smoothed across every edge whose two faces'
/// normals differ by less than `crease_deg` degrees, and flat shading
/// (no normals) when `crease_deg` is 0 or below or no edge is that smooth.
/// Each vertex's normal is the sum of the faces around it that are joined
/// through smooth edges, each weighted by its angle at the vertex (Thürmer
/// and Wüthrich: unlike area weights, how a quad was cut in two does not
/// tilt it); a vertex a crease runs through gets one copy per side.
///
/// Edges are found by position, not by index, so vertices a file splits
/// for their texture coordinates still join. A copied vertex keeps its
/// texture coordinates. Returns, per vertex of the new mesh, the vertex of
/// the old one it copies.
pub fn apply_crease_normals(mesh: &mut TriangleMesh, crease_deg: f32) -> Vec<u32> {
    let identity: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    if crease_deg <= 0.0 || mesh.triangles.is_empty() {
        mesh.normals.clear();
        return identity;
    }
    let unit: Vec<Vec3> = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            (b - a).cross(c - a).normalize_or_zero()
        })
        .collect();
    // At 180 degrees every edge is smooth, opposite faces included.
    let min_cos = if crease_deg >= 180.0 {
        f32::NEG_INFINITY
    } else {
        crease_deg.to_radians().cos()
    };

    // One id per distinct position (-0.0 and 0.0 alike).
    let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
    let weld: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
            let next = welded.len() as u32;
            *welded.entry(key).or_insert(next)
        })
        .collect();

    // Every triangle's edges by their welded ends, sorted so that the
    // triangles sharing an edge are neighbours: (low, high, corner at low,
    // corner at high), a corner being 3 * triangle + k.
    let mut edges: Vec<(u32, u32, u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 3);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (ka, kb) = (k, (k + 1) % 3);
            let (wa, wb) = (weld[tri[ka] as usize], weld[tri[kb] as usize]);
            let (ca, cb) = (3 * t as u32 + ka as u32, 3 * t as u32 + kb as u32);
            edges.push(if wa <= wb {
                (wa, wb, ca, cb)
            } else {
                (wb, wa, cb, ca)
            });
        }
    }
    edges.sort_unstable();

    let mut corners = UnionFind::new(mesh.triangles.len() * 3);
    let mut any_smooth = false;
    for run in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        // An edge of more faces than a double-sided seam has is left a
        // crease: comparing every pair would be quadratic in a file that
        // repeats one face many times.
        if run.len() > MAX_FACES_SMOOTHED_AT_AN_EDGE {
            continue;
        }
        for (i, first) in run.iter().enumerate() {
            for second in &run[i + 1..] {
                let (f, g) = (first.2 / 3, second.2 / 3);
                let cos = unit[f as usize].dot(unit[g as usize]);
                if f != g && cos >= min_cos {
                    corners.union(first.2, second.2);
                    corners.union(first.3, second.3);
                    // Coplanar neighbours (a quad's diagonal) bend nothing.
                    any_smooth |= cos < 1.0 - 1e-6;
                }
            }
        }
    }

    if !any_smooth {
        mesh.normals.clear();
        return identity;
    }

    // Sums in triangle order: the same mesh always gives the same bits.
    let mut sums: HashMap<u32, Vec3> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let p = tri.map(|i| mesh.positions[i as usize]);
        for k in 0..3 {
            let (to_next, to_prev) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
            let angle = to_next.angle_between(to_prev);
            *sums
                .entry(corners.find(3 * t as u32 + k as u32))
                .or_insert(Vec3::ZERO) += unit[t] * angle;
        }
    }

    // A vertex keeps its index for the first group of corners met at it;
    // further groups get copies at the end.
    let mut first_group: Vec<Option<u32>> = vec![None; mesh.positions.len()];
    let mut copies: HashMap<(u32, u32), u32> = HashMap::new();
    let mut source = identity;
    let mut normals = vec![Vec3::ZERO; mesh.positions.len()];
    for t in 0..mesh.triangles.len() {
        for k in 0..3 {
            let vertex = mesh.triangles[t][k];
            let group = corners.find(3 * t as u32 + k as u32);
            let index = match first_group[vertex as usize] {
                None => {
                    first_group[vertex as usize] = Some(group);
                    normals[vertex as usize] = sums[&group].normalize_or_zero();
                    vertex
                }
                Some(first) if first == group => vertex,
                Some(_) => *copies.entry((vertex, group)).or_insert_with(|| {
                    source.push(vertex);
                    mesh.positions.push(mesh.positions[vertex as usize]);
                    if !mesh.texcoords.is_empty() {
                        mesh.texcoords.push(mesh.texcoords[vertex as usize]);
                    }
                    normals.push(sums[&group].normalize_or_zero());
                    mesh.positions.len() as u32 - 1
                }),
            };
            mesh.triangles[t][k] = index;
        }
    }
    mesh.normals = normals;
    source
}

/// The most faces an edge may join and still be smoothed across (two
/// double-sided faces meet four times at a seam).
const MAX_FACES_SMOOTHED_AT_AN_EDGE: usize = 4;

/// Disjoint sets of corners, with path halving.
struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        // The smaller root wins: the sets do not depend on the order of
        // the unions.
        if a < b {
            self.parent[b as usize] = a;
        } else {
            self.parent[a as usize] = b;
        }
    }
}

/// Where shadow rays leave a smooth-shaded triangle: Hanika's shading-point
/// offset ("Hacking the Shadow Terminator", Ray Tracing Gems II, ch. 4).
/// A smooth triangle stands for a curved surface that bulges out of it; the
/// flat triangle shadows itself where the curved surface would be lit,
/// which draws the saw-tooth terminator of low-poly meshes. The point is
/// lifted, for each vertex, onto that vertex's tangent plane when it lies
/// below it, and the lifts are blended by the barycentrics.
///
/// `point` is the hit on the triangle `vertices`, `barycentrics` its
/// weights for them, `normals` the vertices' unit shading normals turned
/// to the side the shadow rays leave from. Where the point lies on or above
/// every tangent plane (a flat or concave neighbourhood) it comes back
/// unchanged, bit for bit.
#[inline]
pub fn terminator_point(
    point: Vec3,
    vertices: [Vec3; 3],
    normals: [Vec3; 3],
    barycentrics: [f32; 3],
) -> Vec3 {
    let mut lift = Vec3::ZERO;
    for k in 0..3 {
        let below = (point - vertices[k]).dot(normals[k]).min(0.0);
        lift -= normals[k] * (below * barycentrics[k]);
    }
    if lift == Vec3::ZERO {
        point
    } else {
        point + lift
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube of 12 triangles over 8 shared vertices, outward wound.
    fn cube() -> TriangleMesh {
        let positions = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriangleMesh {
            positions,
            triangles,
            normals: Vec::new(),
            texcoords: Vec::new(),
            cutout: None,
        }
    }

    fn face_normal(mesh: &TriangleMesh, t: usize) -> Vec3 {
        let [a, b, c] = mesh.vertices(t as u32);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn a_cube_without_normals_is_flat_at_the_default_crease() {
        // No edge below the crease: flat shading, vertices as they were.
        let mut mesh = cube();
        let source = apply_crease_normals(&mut mesh, DEFAULT_CREASE_ANGLE_DEG);
        assert!(mesh.normals.is_empty());
        assert_eq!(source, (0..8).collect::<Vec<u32>>());
        // Just below its 90 degrees: only the quads' diagonals are smooth,
        // and they bend nothing: still flat.
        let mut mesh = cube();
        apply_crease_normals(&mut mesh, 89.0);
        assert!(mesh.normals.is_empty());
        // Without creases everything is smooth: 8 vertices, diagonal normals.
        let mut smooth = cube();
        apply_crease_normals(&mut smooth, 180.0);
        assert_eq!(smooth.positions.len(), 8);
        let n = smooth.normals[7];
        assert!((n - Vec3::ONE.normalize()).length() < 1e-6, "{n}");
        // An angle of 0: flat shading, no normals at all.
        let mut flat = cube();
        apply_crease_normals(&mut flat, 0.0);
        assert!(flat.normals.is_empty());
        assert_eq!(flat.positions.len(), 8);
    }

    /// An open cylinder of `sides` quads capped at both ends by fans.
    fn capped_cylinder(sides: u32) -> TriangleMesh {
        let mut positions = Vec::new();
        for i in 0..sides {
            let a = i as f32 / sides as f32 * std::f32::consts::TAU;
            positions.push(Vec3::new(a.cos(), 0.0, a.sin()));
            positions.push(Vec3::new(a.cos(), 1.0, a.sin()));
        }
        let (bottom, top) = (2 * sides, 2 * sides + 1);
        positions.push(Vec3::ZERO);
        positions.push(Vec3::Y);
        let mut triangles = Vec::new();
        for i in 0..sides {
            let j = (i + 1) % sides;
            let (b0, t0, b1, t1) = (2 * i, 2 * i + 1, 2 * j, 2 * j + 1);
            triangles.push([b0, t0, t1]);
            triangles.push([b0, t1, b1]);
            triangles.push([bottom, b0, b1]);
            triangles.push([top, t1, t0]);
        }
        TriangleMesh {
            positions,
            triangles,
            normals: Vec::new(),
            texcoords: Vec::new(),
            cutout: None,
        }
    }

    #[test]
    fn one_face_repeated_many_times_is_not_compared_pair_by_pair() {
        let mut mesh = TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.5, 0.5, 1.0)],
            triangles: [[0, 1, 2], [0, 3, 1]].repeat(50_000),
            normals: Vec::new(),
            texcoords: Vec::new(),
            cutout: None,
        };
        let start = std::time::Instant::now();
        apply_crease_normals(&mut mesh, 180.0);
        // Pair by pair, 10^10 comparisons: hours. Edge by edge: well
        // under a second, even in a debug build.
        assert!(
            start.elapsed().as_secs_f64() < 10.0,
            "{:?}",
            start.elapsed()
        );
    }

    #[test]
    fn a_vertex_split_at_a_crease_keeps_its_texture_coordinates() {
        let mut mesh = capped_cylinder(24);
        mesh.texcoords = (0..mesh.positions.len())
            .map(|i| glam::Vec2::new(i as f32, 0.5))
            .collect();
        let source = apply_crease_normals(&mut mesh, DEFAULT_CREASE_ANGLE_DEG);
        assert!(
            source.len() > mesh.positions.len() / 2,
            "some vertices split"
        );
        assert_eq!(mesh.texcoords.len(), mesh.positions.len());
        for (vertex, &from) in source.iter().enumerate() {
            assert_eq!(mesh.texcoords[vertex].x, from as f32, "vertex {vertex}");
        }
    }

    #[test]
    fn a_cylinder_is_smooth_around_and_sharp_at_its_caps() {
        // 24 sides: 15 degrees between neighbouring sides, 90 at the caps.
        let mut mesh = capped_cylinder(24);
        apply_crease_normals(&mut mesh, DEFAULT_CREASE_ANGLE_DEG);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let face = face_normal(&mesh, t);
            for &v in tri {
                let p = mesh.positions[v as usize];
                let n = mesh.normals[v as usize];
                if face.y.abs() > 0.99 {
                    // Caps: flat, their own normal.
                    assert!((n - face).length() < 1e-6, "cap {t}: {n}");
                } else {
                    // Sides: the radial direction, as on a true cylinder.
                    let radial = Vec3::new(p.x, 0.0, p.z).normalize();
                    assert!((n - radial).length() < 1e-5, "side {t}: {n} vs {radial}");
                }
            }
        }
        // A crease below the sides' 15 degrees makes the sides flat too:
        // nothing is smooth.
        let mut faceted = capped_cylinder(24);
        apply_crease_normals(&mut faceted, 10.0);
        assert!(faceted.normals.is_empty());
    }

    #[test]
    fn vertices_split_only_for_their_texture_coordinates_still_join() {
        // Two triangles of a shallow roof, the shared edge's vertices
        // duplicated (as a file does for texture coordinates).
        let mut mesh = TriangleMesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.1, 0.5),
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(-1.0, 0.1, 0.5),
            ],
            triangles: vec![[0, 1, 2], [4, 3, 5]],
            normals: Vec::new(),
            texcoords: Vec::new(),
            cutout: None,
        };
        apply_crease_normals(&mut mesh, DEFAULT_CREASE_ANGLE_DEG);
        assert_eq!(mesh.positions.len(), 6);
        for v in [0, 1, 3, 4] {
            assert!((mesh.normals[v] - Vec3::Y).length() < 1e-6, "{v}");
        }
    }

    #[test]
    fn the_terminator_point_moves_only_off_curved_triangles() {
        let vertices = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let point = Vec3::new(0.25, 0.0, 0.25);
        let b = [0.5, 0.25, 0.25];
        // Flat: every vertex normal the face's. Unchanged, bit for bit.
        assert_eq!(terminator_point(point, vertices, [Vec3::Y; 3], b), point);
        // Bulging (normals leaning outward, as on a sphere): lifted above
        // the triangle, toward where the curved surface is.
        let out = [
            Vec3::new(-1.0, 1.0, -1.0).normalize(),
            Vec3::new(1.0, 1.0, -0.2).normalize(),
            Vec3::new(-0.2, 1.0, 1.0).normalize(),
        ];
        let lifted = terminator_point(point, vertices, out, b);
        assert!(lifted.y > 0.01, "{lifted}");
        // Hollow (normals leaning inward): the point is above every tangent
        // plane already and stays.
        let inward = out.map(|n| Vec3::new(-n.x, n.y, -n.z));
        assert_eq!(terminator_point(point, vertices, inward, b), point);
    }
}
