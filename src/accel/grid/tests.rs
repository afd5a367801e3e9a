//! Tests of the grid backend: DDA edge cases, watertightness, stable
//! spheres, instances, agreement with brute force and with Embree.

use std::collections::HashSet;
use std::f32::consts::PI;

use glam::{Affine3A, Quat, Vec3};
use proptest::prelude::*;

use super::*;
use crate::accel::embree::EmbreeIntersector;
use crate::accel::{Accelerator, BackendKind};
use crate::geometry::{Plane, TriangleMesh, MOTION_STEPS};
use crate::ray::{HitPacket, RayPacket, PACKET_WIDTH};

mod against_embree;

/// The crate's seeded generator, with the shapes these tests draw.
struct Rng(crate::rng::SplitMix64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(crate::rng::SplitMix64(seed))
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        self.0.range(lo, hi)
    }

    fn vec_in(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = self.vec_in(Vec3::splat(-1.0), Vec3::ONE);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

fn object(shape: Shape, placement: Placement) -> Object {
    Object {
        name: String::new(),
        shape,
        material: 0,
        placement,
    }
}

fn world(shape: Shape) -> Object {
    object(shape, Placement::World)
}

fn sphere(center: Vec3, radius: f32) -> Shape {
    Shape::Sphere(Sphere { center, radius })
}

/// A closed icosphere: subdivided icosahedron, vertices shared by index.
fn icosphere(subdivisions: u32, center: Vec3, radius: f32) -> TriangleMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from(*p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = ((positions[a as usize] + positions[b as usize]) * 0.5).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    TriangleMesh {
        positions: positions.iter().map(|p| center + *p * radius).collect(),
        triangles,
        normals: Vec::new(),
        texcoords: Vec::new(),
        cutout: None,
    }
}

/// A bumpy closed blob standing in for the bunny: an icosphere with every
/// vertex pushed in or out by a smooth pseudo-random amount.
fn blob(subdivisions: u32, seed: u64) -> TriangleMesh {
    let mut mesh = icosphere(subdivisions, Vec3::ZERO, 1.0);
    let mut rng = Rng::new(seed);
    let waves: Vec<(Vec3, f32, f32)> = (0..6)
        .map(|_| (rng.unit_vector(), rng.range(2.0, 7.0), rng.range(0.0, 6.0)))
        .collect();
    for p in &mut mesh.positions {
        let bump: f32 = waves
            .iter()
            .map(|(k, f, phase)| (k.dot(*p) * f + phase).sin() * 0.06)
            .sum();
        *p *= 1.0 + bump;
        *p = Vec3::new(p.x * 1.2, p.y, p.z * 0.9) + Vec3::new(0.1, 0.3, -0.2);
    }
    mesh
}

/// A closed cube of `n x n` quads per face, two triangles each.
fn cube(n: u32, center: Vec3, half: f32) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    // Grid coordinates on a face, exact for the shared edges: every face
    // uses the same values for the same positions.
    let coord = |i: u32| -half + 2.0 * half * i as f32 / n as f32;
    for axis in 0..3 {
        for side in [-half, half] {
            let base = mesh.positions.len() as u32;
            for j in 0..=n {
                for i in 0..=n {
                    let mut p = Vec3::ZERO;
                    p[axis] = side;
                    p[(axis + 1) % 3] = coord(i);
                    p[(axis + 2) % 3] = coord(j);
                    mesh.positions.push(center + p);
                }
            }
            let at = |i: u32, j: u32| base + j * (n + 1) + i;
            for j in 0..n {
                for i in 0..n {
                    mesh.triangles
                        .push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    mesh.triangles
                        .push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
    mesh
}

/// The closest hit over every primitive of every object, no acceleration.
fn brute_force(objects: &[Object], ray: &Ray) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    for (id, obj) in objects.iter().enumerate() {
        let (o, d) = match obj.placement.transform_at(ray.time) {
            None => (ray.origin, ray.dir),
            Some(xf) => {
                let inv = xf.inverse();
                (
                    inv.transform_point3(ray.origin),
                    inv.transform_vector3(ray.dir),
                )
            }
        };
        let tmax = best.map_or(ray.tmax, |h| h.t);
        match &obj.shape {
            Shape::Mesh(mesh) => {
                let Some(wt) = WatertightRay::new(o, d) else {
                    continue;
                };
                for prim in 0..mesh.triangles.len() as u32 {
                    let tmax = best.map_or(ray.tmax, |h| h.t);
                    if let Some(h) = wt.intersect_triangle(&mesh.vertices(prim), ray.tmin, tmax) {
                        best = Some(Hit {
                            t: h.t,
                            object: id as u32,
                            prim,
                            u: h.u,
                            v: h.v,
                        });
                    }
                }
            }
            Shape::Sphere(s) => {
                // Placed spheres are traced in the world, where they are
                // placed (or not at all, when the transform is not round).
                let placed = match &obj.placement {
                    Placement::World => Some(*s),
                    Placement::Instance(xf) => crate::accel::placed_sphere(s, xf),
                    Placement::Moving(motion) => {
                        crate::accel::moving_sphere(s, motion).map(|m| m.at(ray.time))
                    }
                };
                let hit =
                    placed.and_then(|s| intersect_sphere(&s, ray.origin, ray.dir, ray.tmin, tmax));
                if let Some(t) = hit {
                    best = Some(Hit {
                        t,
                        object: id as u32,
                        prim: 0,
                        u: 0.0,
                        v: 0.0,
                    });
                }
            }
            Shape::Plane(_) => {}
        }
    }
    best
}

fn test_cells(spec: GridSpec) -> Cells {
    bin(&Prims::default(), &[], spec)
}

/// The cells the DDA visits, until it stops on its own.
fn dda_cells(cells: &Cells, ray: &Ray) -> Vec<[i32; 3]> {
    let Some(mut dda) = Prepared::new(ray).and_then(|p| Dda::new(cells, ray, p.inv_dir)) else {
        return Vec::new();
    };
    let mut out = vec![dda.cell];
    while dda.step(ray.tmax) {
        assert_eq!(
            dda.index,
            cells.spec.linear_index(dda.cell.map(|c| c as u32)),
            "linear index out of step"
        );
        out.push(dda.cell);
        assert!(out.len() < 10_000, "DDA does not end");
    }
    out
}

fn unit_spec(n: [u32; 3]) -> GridSpec {
    GridSpec::new(
        Aabb {
            min: Vec3::ZERO,
            max: Vec3::from(n.map(|x| x as f32)),
        },
        n,
    )
}

#[test]
fn dda_axis_parallel_and_negative_zero_directions() {
    let cells = test_cells(unit_spec([4, 3, 2]));
    let along_x = dda_cells(&cells, &Ray::new(Vec3::new(-1.0, 1.5, 0.5), Vec3::X));
    assert_eq!(along_x, vec![[0, 1, 0], [1, 1, 0], [2, 1, 0], [3, 1, 0]]);
    for dir in [
        Vec3::new(1.0, -0.0, 0.0),
        Vec3::new(1.0, 0.0, -0.0),
        Vec3::new(1.0, -0.0, -0.0),
    ] {
        assert_eq!(
            dda_cells(&cells, &Ray::new(Vec3::new(-1.0, 1.5, 0.5), dir)),
            along_x
        );
    }
    let back = dda_cells(&cells, &Ray::new(Vec3::new(9.0, 1.5, 0.5), -Vec3::X));
    assert_eq!(back, vec![[3, 1, 0], [2, 1, 0], [1, 1, 0], [0, 1, 0]]);
    let down = dda_cells(&cells, &Ray::new(Vec3::new(2.5, 5.0, 1.5), -Vec3::Y));
    assert_eq!(down, vec![[2, 2, 1], [2, 1, 1], [2, 0, 1]]);
}

#[test]
fn dda_origin_on_voxel_planes() {
    let cells = test_cells(unit_spec([4, 4, 4]));
    // On the plane x = 2, moving along it: stays in one column next to it.
    let w = dda_cells(&cells, &Ray::new(Vec3::new(2.0, 0.5, 0.5), Vec3::Y));
    assert_eq!(w.len(), 4);
    assert!(w.iter().all(|c| c[0] == 1 || c[0] == 2) && w.iter().all(|c| c[0] == w[0][0]));
    // On x = 2 moving +x or -x: every cell ahead is visited, in order.
    let w = dda_cells(&cells, &Ray::new(Vec3::new(2.0, 0.5, 0.5), Vec3::X));
    assert_eq!(w, vec![[2, 0, 0], [3, 0, 0]]);
    let w = dda_cells(&cells, &Ray::new(Vec3::new(2.0, 0.5, 0.5), -Vec3::X));
    assert_eq!(w.last(), Some(&[0, 0, 0]));
    assert!(w.contains(&[1, 0, 0]));
    // On a grid corner, diagonally: the diagonal cells.
    let w = dda_cells(&cells, &Ray::new(Vec3::ZERO, Vec3::ONE));
    assert_eq!(w.first(), Some(&[0, 0, 0]));
    assert_eq!(w.last(), Some(&[3, 3, 3]));
    for c in [[1, 1, 1], [2, 2, 2]] {
        assert!(w.contains(&c));
    }
    // On the grid's max face, leaving: one cell at most, then done.
    let w = dda_cells(&cells, &Ray::new(Vec3::new(4.0, 0.5, 0.5), Vec3::X));
    assert!(w.len() <= 1);
}

#[test]
fn dda_outside_origins_misses_and_t_ranges() {
    let cells = test_cells(unit_spec([4, 4, 4]));
    // From outside: starts at the entry cell.
    let w = dda_cells(
        &cells,
        &Ray::new(Vec3::new(-3.0, 2.5, 10.0), Vec3::new(1.0, 0.0, -2.0)),
    );
    assert_eq!(w.first(), Some(&[0, 2, 3]));
    // Misses: parallel outside, pointing away, passing beside.
    assert!(dda_cells(&cells, &Ray::new(Vec3::new(-1.0, 5.0, 1.0), Vec3::X)).is_empty());
    assert!(dda_cells(&cells, &Ray::new(Vec3::new(-1.0, 1.0, 1.0), -Vec3::X)).is_empty());
    assert!(dda_cells(
        &cells,
        &Ray::new(Vec3::new(-1.0, 1.0, 1.0), Vec3::new(1.0, 10.0, 0.0))
    )
    .is_empty());
    // tmin and tmax cut the walk.
    let mut ray = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
    ray.tmin = 2.5;
    ray.tmax = 3.5;
    assert_eq!(dda_cells(&cells, &ray), vec![[1, 0, 0], [2, 0, 0]]);
    ray.tmax = 0.5;
    ray.tmin = 0.0;
    assert!(dda_cells(&cells, &ray).is_empty());
    // NaN and zero directions: nothing.
    assert!(dda_cells(&cells, &Ray::new(Vec3::splat(1.5), Vec3::NAN)).is_empty());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// The DDA's cells are a 6-connected path, within the supercover of the
    /// ray, containing the cell of every point of the ray that is clearly
    /// inside a cell.
    #[test]
    fn dda_follows_the_ray(
        n in (1u32..9, 1u32..9, 1u32..9),
        o in (-3.0f32..11.0, -3.0f32..11.0, -3.0f32..11.0),
        target in (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0),
        zero in 0u8..16,
    ) {
        let n = [n.0, n.1, n.2];
        let spec = unit_spec(n);
        let cells = test_cells(spec);
        // Aimed at a point of the grid (most rays enter it).
        let mut d = Vec3::from(target) * spec.bounds.max - Vec3::from(o);
        if zero < 3 {
            d[zero as usize] = if zero % 2 == 0 { 0.0 } else { -0.0 };
        }
        prop_assume!(d.length() > 1e-3);
        let ray = Ray::new(Vec3::from(o), d);
        let visited = dda_cells(&cells, &ray);
        for w in visited.windows(2) {
            let moved: i32 = (0..3).map(|a| (w[0][a] - w[1][a]).abs()).sum();
            prop_assert_eq!(moved, 1, "not 6-connected: {:?}", w);
        }
        let visited: HashSet<[u32; 3]> = visited.iter().map(|c| c.map(|x| x as u32)).collect();
        // Within the supercover, grown a little for the f32 rounding.
        let cover: HashSet<[u32; 3]> = spec.walk(ray.origin, ray.dir, 0.0, f32::INFINITY).collect();
        for c in &visited {
            if !cover.contains(c) {
                let b = spec.voxel_bounds(*c);
                let grown = Aabb { min: b.min - 1e-4, max: b.max + 1e-4 };
                let near = GridSpec::new(grown, [1, 1, 1]).walk(ray.origin, ray.dir, 0.0, f32::INFINITY).count();
                prop_assert!(near > 0, "cell {:?} is not near the ray", c);
            }
        }
        // Every point well inside a cell is in a visited cell.
        for i in 0..400 {
            let p = ray.at(i as f32 * 0.05);
            let inside = (0..3).all(|a| {
                let f = p[a] - p[a].floor();
                p[a] > 0.0 && p[a] < n[a] as f32 && f > 1e-3 && f < 1.0 - 1e-3
            });
            if inside {
                let c = p.to_array().map(|x| x.floor() as u32);
                prop_assert!(visited.contains(&c), "cell {:?} at t = {} skipped", c, i as f32 * 0.05);
            }
        }
    }
}

fn assert_all_hit(grid: &GridIntersector, rays: &[Ray], what: &str) {
    for (i, ray) in rays.iter().enumerate() {
        assert!(
            grid.intersect(ray).is_some(),
            "{what}: ray {i} {ray:?} slipped through"
        );
        assert!(grid.occluded(ray), "{what}: ray {i} {ray:?} not occluded");
    }
}

#[test]
fn random_rays_from_inside_closed_meshes_all_hit() {
    let mut rng = Rng::new(7);
    let meshes = [
        ("icosphere", icosphere(4, Vec3::new(0.3, -0.2, 0.1), 1.0)),
        ("cube", cube(5, Vec3::new(-0.25, 0.5, 0.0), 0.8)),
        ("blob", blob(3, 11)),
        // Tiny and far from the origin (DESIGN 6).
        ("tiny cube", cube(4, Vec3::splat(2e-4), 1e-4)),
        (
            "far icosphere",
            icosphere(3, Vec3::new(1e5, -2e5, 5e4), 30.0),
        ),
    ];
    for (name, mesh) in meshes {
        let bounds = mesh.bounds();
        let center = bounds.center();
        let size = bounds.extent().min_element();
        let objects = vec![world(Shape::Mesh(mesh))];
        let rays: Vec<Ray> = (0..20_000)
            .map(|_| {
                let o = center + rng.unit_vector() * size * rng.range(0.0, 0.2);
                Ray::new(o, rng.unit_vector())
            })
            .collect();
        for resolution in [None, Some([1, 1, 1]), Some([7, 5, 6]), Some([40, 40, 40])] {
            let grid = GridIntersector::build(&objects, resolution);
            assert_all_hit(&grid, &rays, &format!("{name} {resolution:?}"));
        }
    }
}

#[test]
fn rays_at_shared_edges_and_vertices_of_a_tessellated_quad_hit() {
    // An 8 x 8 quad grid of 128 triangles (shared vertices), tilted.
    let n = 8u32;
    let xf = Affine3A::from_rotation_translation(
        Quat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 0.2),
        Vec3::new(0.5, -0.25, 2.0),
    );
    let mut mesh = TriangleMesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let p = Vec3::new(
                i as f32 / n as f32 * 2.0 - 1.0,
                j as f32 / n as f32 * 2.0 - 1.0,
                0.0,
            );
            mesh.positions.push(xf.transform_point3(p));
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            mesh.triangles
                .push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            mesh.triangles
                .push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    // Targets: every inner vertex and the midpoint of every inner edge.
    let mut targets = Vec::new();
    for j in 1..n {
        for i in 1..n {
            targets.push(mesh.positions[at(i, j) as usize]);
        }
    }
    for [a, b, c] in &mesh.triangles {
        for (x, y) in [(a, b), (b, c), (c, a)] {
            let p = (mesh.positions[*x as usize] + mesh.positions[*y as usize]) * 0.5;
            let q = xf.inverse().transform_point3(p);
            if q.x.abs() < 0.99 && q.y.abs() < 0.99 {
                targets.push(p);
            }
        }
    }
    let objects = vec![world(Shape::Mesh(mesh))];
    let origins = [
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::new(2.0, 1.0, 6.0),
        Vec3::new(-4.0, 3.0, 2.0),
    ];
    let rays: Vec<Ray> = origins
        .iter()
        .flat_map(|o| targets.iter().map(move |t| Ray::new(*o, *t - *o)))
        .collect();
    for resolution in [None, Some([8, 8, 8]), Some([3, 16, 5])] {
        let grid = GridIntersector::build(&objects, resolution);
        assert_all_hit(&grid, &rays, &format!("quad {resolution:?}"));
        for ray in &rays {
            assert!((grid.intersect(ray).unwrap().t - 1.0).abs() < 1e-5);
        }
    }
}

#[test]
fn spheres_tiny_far_away_and_huge_around_the_origin() {
    let tiny = Sphere {
        center: Vec3::new(600.0, 0.0, -800.0),
        radius: 1e-4,
    };
    let objects = vec![
        world(Shape::Sphere(tiny)),
        world(sphere(Vec3::new(5.0, 5.0, 5.0), 1.0)),
        world(Shape::Mesh(icosphere(1, Vec3::new(-3.0, 0.0, -2.0), 0.5))),
    ];
    let grid = GridIntersector::build(&objects, None);
    for i in -3..=3 {
        for j in -3..=3 {
            let aim = tiny.center + Vec3::new(i as f32, j as f32, 0.0) * 0.25e-4;
            let hit = grid
                .intersect(&Ray::new(Vec3::ZERO, aim))
                .expect("tiny sphere missed");
            assert_eq!(hit.object, 0);
            assert!((hit.t - 1.0).abs() < 2e-7, "t = {}", hit.t);
        }
    }
    let beside = tiny.center + Vec3::new(0.0, 3e-4, 0.0);
    assert!(grid.intersect(&Ray::new(Vec3::ZERO, beside)).is_none());

    let objects = vec![
        world(sphere(Vec3::new(1.0, -2.0, 0.5), 1e4)),
        world(Shape::Mesh(cube(1, Vec3::ZERO, 0.5))),
    ];
    let grid = GridIntersector::build(&objects, None);
    let mut rng = Rng::new(3);
    for _ in 0..1000 {
        let dir = rng.unit_vector();
        let ray = Ray::new(Vec3::new(0.0, 0.0, 0.0), dir);
        // The cube around the origin comes first; past it, the far side of
        // the huge sphere.
        assert_eq!(grid.intersect(&ray).unwrap().object, 1);
        let mut past = ray;
        past.tmin = 1.0;
        let hit = grid
            .intersect(&past)
            .expect("huge sphere missed from inside");
        assert_eq!(hit.object, 0);
        let r = (ray.at(hit.t) - Vec3::new(1.0, -2.0, 0.5)).length();
        assert!((r - 1e4).abs() < 3e-3, "|p - c| = {r}");
    }
}

/// Hit distances agree to 1e-4 relative, plus the rounding of the origin's
/// coordinates (a hit a hair from the origin has no relative precision).
fn same_distance(ray: &Ray, a: f32, b: f32) -> bool {
    let len = ray.dir.length();
    (a - b).abs() * len <= 1e-4 * b.abs() * len + 1e-5 * (ray.origin.length() + 1.0)
}

fn random_instances(rng: &mut Rng) -> Vec<(Shape, Affine3A)> {
    let mesh = blob(2, 5);
    (0..6)
        .map(|i| {
            let rotation = Quat::from_axis_angle(rng.unit_vector(), rng.range(0.0, 2.0 * PI));
            let translation = rng.vec_in(Vec3::splat(-4.0), Vec3::splat(4.0));
            if i % 2 == 0 {
                let scale = rng.vec_in(Vec3::splat(0.3), Vec3::splat(1.5));
                (
                    Shape::Mesh(mesh.clone()),
                    Affine3A::from_scale_rotation_translation(scale, rotation, translation),
                )
            } else {
                // Spheres under a uniform scale, so a world sphere matches.
                let scale = Vec3::splat(rng.range(0.3, 1.5));
                (
                    sphere(Vec3::new(0.2, -0.1, 0.3), 0.7),
                    Affine3A::from_scale_rotation_translation(scale, rotation, translation),
                )
            }
        })
        .collect()
}

/// The same shape with the transform applied to its coordinates.
fn baked(shape: &Shape, xf: &Affine3A) -> Shape {
    match shape {
        Shape::Mesh(mesh) => Shape::Mesh(TriangleMesh {
            positions: mesh
                .positions
                .iter()
                .map(|p| xf.transform_point3(*p))
                .collect(),
            triangles: mesh.triangles.clone(),
            normals: Vec::new(),
            texcoords: Vec::new(),
            cutout: None,
        }),
        Shape::Sphere(s) => sphere(
            xf.transform_point3(s.center),
            s.radius * xf.matrix3.x_axis.length(),
        ),
        Shape::Plane(p) => Shape::Plane(*p),
    }
}

#[test]
fn instances_hit_like_their_world_space_copies() {
    let mut rng = Rng::new(19);
    let instances = random_instances(&mut rng);
    let mut inst_objects = vec![world(sphere(Vec3::new(0.0, -30.0, 0.0), 20.0))];
    let mut world_objects = inst_objects.clone();
    for (shape, xf) in &instances {
        inst_objects.push(object(shape.clone(), Placement::Instance(*xf)));
        world_objects.push(world(baked(shape, xf)));
    }
    // A non-invertible instance and an empty one are ignored.
    inst_objects.push(object(
        sphere(Vec3::ZERO, 1.0),
        Placement::Instance(Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))),
    ));
    inst_objects.push(object(
        Shape::Mesh(TriangleMesh::default()),
        Placement::Instance(Affine3A::IDENTITY),
    ));
    let a = GridIntersector::build(&inst_objects, None);
    let b = GridIntersector::build(&world_objects, None);
    let (mut hits, mut checked) = (0, 0);
    for _ in 0..20_000 {
        let o = rng.vec_in(Vec3::splat(-9.0), Vec3::splat(9.0));
        let target = rng.vec_in(Vec3::splat(-5.0), Vec3::splat(5.0));
        let ray = Ray::new(o, (target - o) * rng.range(0.1, 3.0));
        let (x, y) = (a.intersect(&ray), b.intersect(&ray));
        assert_eq!(x, brute_force(&inst_objects, &ray));
        match (x, y) {
            (Some(x), Some(y)) => {
                hits += 1;
                assert!(same_distance(&ray, x.t, y.t), "{x:?} vs {y:?}");
                if x.object == y.object && x.prim == y.prim {
                    checked += 1;
                    assert!((x.u - y.u).abs() < 1e-3 && (x.v - y.v).abs() < 1e-3);
                }
            }
            (None, None) => {}
            (x, y) => {
                // Only rays grazing an edge or a silhouette may differ.
                let h = x.or(y).unwrap();
                let graze = h.u.min(h.v).min(1.0 - h.u - h.v) < 1e-3;
                assert!(graze, "instance {x:?} vs world {y:?} for {ray:?}");
            }
        }
        assert_eq!(a.occluded(&ray), x.is_some());
    }
    assert!(
        hits > 3_000 && checked > hits * 9 / 10,
        "{hits} hits, {checked} checked"
    );
}

#[test]
fn moving_instances_match_a_fresh_build() {
    let mut rng = Rng::new(23);
    let mut objects = vec![world(sphere(Vec3::new(0.0, -30.0, 0.0), 20.0))];
    for (shape, xf) in random_instances(&mut rng) {
        objects.push(object(shape, Placement::Instance(xf)));
    }
    objects.push(world(Shape::Mesh(icosphere(
        2,
        Vec3::new(3.0, 3.0, 3.0),
        1.0,
    ))));
    let mut grid = GridIntersector::build(&objects, None);
    assert!(
        !grid.set_instance_transform(0, &Affine3A::IDENTITY),
        "not an instance"
    );
    assert!(
        !grid.set_instance_transform(99, &Affine3A::IDENTITY),
        "no such object"
    );
    let singular = Affine3A::from_scale(Vec3::new(1.0, 1.0, 0.0));
    assert!(!grid.set_instance_transform(1, &singular));
    for frame in 0..5 {
        for id in 1..objects.len() - 1 {
            let xf = Affine3A::from_rotation_translation(
                Quat::from_axis_angle(rng.unit_vector(), rng.range(0.0, PI)),
                rng.vec_in(Vec3::splat(-6.0), Vec3::splat(6.0)),
            ) * Affine3A::from_scale(Vec3::splat(rng.range(0.5, 2.0)));
            objects[id].placement = Placement::Instance(xf);
            assert!(grid.set_instance_transform(id as u32, &xf));
        }
        let fresh = GridIntersector::build(&objects, None);
        for _ in 0..2_000 {
            let o = rng.vec_in(Vec3::splat(-10.0), Vec3::splat(10.0));
            let ray = Ray::new(o, rng.vec_in(Vec3::splat(-6.0), Vec3::splat(6.0)) - o);
            let hit = grid.intersect(&ray);
            assert_eq!(hit, fresh.intersect(&ray), "frame {frame}");
            assert_eq!(hit, brute_force(&objects, &ray), "frame {frame}");
            assert_eq!(grid.occluded(&ray), hit.is_some());
        }
    }
}

/// A rigid motion over the shutter: turning and sliding, each pose a
/// similarity (so spheres stay round at every pose).
fn random_motion(rng: &mut Rng, start: &Affine3A) -> Motion {
    let axis = rng.unit_vector();
    let turn = rng.range(0.0, 1.0);
    let slide = rng.vec_in(Vec3::splat(-2.0), Vec3::splat(2.0));
    Motion {
        poses: std::array::from_fn(|step| {
            let f = step as f32 / (MOTION_STEPS - 1) as f32;
            Affine3A::from_rotation_translation(Quat::from_axis_angle(axis, turn * f), slide * f)
                * *start
        }),
    }
}

#[test]
fn objects_moving_over_the_shutter_are_met_where_each_ray_time_puts_them() {
    let mut rng = Rng::new(29);
    let mut objects = vec![world(sphere(Vec3::new(0.0, -30.0, 0.0), 20.0))];
    for (shape, xf) in random_instances(&mut rng) {
        let motion = random_motion(&mut rng, &xf);
        objects.push(object(shape, Placement::Moving(motion)));
    }
    let mut grid = GridIntersector::build(&objects, None);
    let mut embree = EmbreeIntersector::build(&objects).unwrap();
    let (mut hits, mut moving_hits, mut disagreements) = (0, 0, 0);
    for round in 0..2 {
        if round == 1 {
            // A new shutter: every object given a new motion.
            let mut placements = Vec::new();
            for (id, object) in objects.iter_mut().enumerate().skip(1) {
                let start =
                    Affine3A::from_translation(rng.vec_in(Vec3::splat(-3.0), Vec3::splat(3.0)));
                object.placement = Placement::Moving(random_motion(&mut rng, &start));
                placements.push((id as u32, object.placement));
            }
            assert!(grid.place_objects(&placements));
            embree.place_objects(&placements).unwrap();
        }
        for _ in 0..5_000 {
            let o = rng.vec_in(Vec3::splat(-10.0), Vec3::splat(10.0));
            let ray = Ray::new(o, rng.vec_in(Vec3::splat(-5.0), Vec3::splat(5.0)) - o)
                .at_time(rng.range(0.0, 1.0));
            let hit = grid.intersect(&ray);
            assert_eq!(hit, brute_force(&objects, &ray), "round {round}");
            assert_eq!(grid.occluded(&ray), hit.is_some());
            let other = embree.intersect(&ray);
            match (hit, other) {
                (Some(g), Some(e)) if g.object == e.object && same_distance(&ray, g.t, e.t) => {
                    hits += 1;
                    moving_hits += usize::from(g.object > 0);
                }
                (None, None) => {}
                // Grazing a silhouette or an edge, where the two round apart.
                _ => disagreements += 1,
            }
        }
    }
    assert!(
        hits > 2_000 && moving_hits > 1_000,
        "{hits} hits, {moving_hits} on movers"
    );
    assert!(
        disagreements <= 10,
        "{disagreements} rays met differently by Embree"
    );
    // The same ray at two times meets a moving object in two places.
    let mover = Ray::new(Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.0, 0.0, -1.0));
    let single = vec![object(
        sphere(Vec3::ZERO, 1.0),
        Placement::Moving(Motion {
            poses: std::array::from_fn(|step| {
                Affine3A::from_translation(Vec3::new(0.0, 0.0, step as f32))
            }),
        }),
    )];
    let grid = GridIntersector::build(&single, None);
    let embree = EmbreeIntersector::build(&single).unwrap();
    for time in [0.0, 0.5, 1.0] {
        let expected = 9.0 - 4.0 * time;
        for hit in [
            grid.intersect(&mover.at_time(time)),
            embree.intersect(&mover.at_time(time)),
        ] {
            let t = hit.expect("the ball is on the ray").t;
            assert!(
                (t - expected).abs() < 1e-4,
                "time {time}: t {t}, not {expected}"
            );
        }
    }
}

#[test]
fn agrees_with_brute_force_on_a_random_triangle_soup() {
    let mut rng = Rng::new(42);
    let mut mesh = TriangleMesh::default();
    for i in 0..400 {
        let c = rng.vec_in(Vec3::splat(-5.0), Vec3::splat(5.0));
        let size = if i % 10 == 0 { 4.0 } else { 0.6 };
        let base = mesh.positions.len() as u32;
        for _ in 0..3 {
            mesh.positions
                .push(c + rng.vec_in(Vec3::splat(-size), Vec3::splat(size)));
        }
        if i % 50 == 0 {
            // Degenerate: a repeated vertex.
            mesh.positions[base as usize + 2] = mesh.positions[base as usize];
        }
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    let mut objects = vec![world(Shape::Mesh(mesh))];
    for _ in 0..10 {
        objects.push(world(sphere(
            rng.vec_in(Vec3::splat(-5.0), Vec3::splat(5.0)),
            rng.range(0.05, 1.0),
        )));
    }
    objects.push(world(Shape::Plane(Plane {
        point: Vec3::ZERO,
        normal: Vec3::Y,
    })));
    for resolution in [None, Some([1, 1, 1]), Some([17, 3, 9]), Some([64, 64, 64])] {
        let grid = GridIntersector::build(&objects, resolution);
        let mut hits = 0;
        for i in 0..5_000 {
            let o = rng.vec_in(Vec3::splat(-8.0), Vec3::splat(8.0));
            let dir = if i % 2 == 0 {
                rng.unit_vector()
            } else {
                // Aimed into the soup, where most triangles are.
                (rng.vec_in(Vec3::splat(-4.0), Vec3::splat(4.0)) - o).normalize()
            };
            let mut ray = Ray::new(o, dir * rng.range(0.01, 10.0));
            if i % 3 == 0 {
                ray.tmin = rng.range(0.0, 1.0);
                ray.tmax = ray.tmin + rng.range(0.0, 3.0);
            }
            let expected = brute_force(&objects, &ray);
            let got = grid.intersect(&ray);
            match (got, expected) {
                (Some(g), Some(e)) => {
                    hits += 1;
                    // Same tests on the same inputs: the same t exactly; a
                    // different primitive only on an exact tie.
                    assert_eq!(g.t, e.t, "{resolution:?} {ray:?}");
                    if (g.object, g.prim) != (e.object, e.prim) {
                        assert_eq!(g.t, e.t);
                    } else {
                        assert_eq!(g, e);
                    }
                }
                (g, e) => assert_eq!(g, e, "{resolution:?} {ray:?}"),
            }
            assert_eq!(
                grid.occluded(&ray),
                expected.is_some(),
                "{resolution:?} {ray:?}"
            );
        }
        assert!(hits > 1_500, "only {hits} hits");
    }
}

#[test]
fn empty_and_degenerate_scenes() {
    let nothing = GridIntersector::build(&[], None);
    let ray = Ray::new(Vec3::ZERO, Vec3::X);
    assert!(nothing.intersect(&ray).is_none() && !nothing.occluded(&ray));
    assert!(nothing.spec().is_none());

    let degenerate = TriangleMesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::X * 2.0,
            Vec3::new(f32::NAN, 0.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 0, 0], [0, 1, 3]],
        normals: Vec::new(),
        texcoords: Vec::new(),
        cutout: None,
    };
    let objects = vec![
        world(Shape::Mesh(TriangleMesh::default())),
        world(Shape::Plane(Plane {
            point: Vec3::ZERO,
            normal: Vec3::Y,
        })),
        world(Shape::Mesh(degenerate)),
        object(
            Shape::Mesh(TriangleMesh::default()),
            Placement::Instance(Affine3A::IDENTITY),
        ),
    ];
    for resolution in [None, Some([3, 3, 3])] {
        let grid = GridIntersector::build(&objects, resolution);
        for dir in [Vec3::X, -Vec3::Y, Vec3::new(0.0, -1.0, 0.1), Vec3::ZERO] {
            let ray = Ray::new(Vec3::new(1.0, 1.0, 0.0), dir);
            assert!(grid.intersect(&ray).is_none() && !grid.occluded(&ray));
        }
    }
    // A flat scene (one quad in a plane) gets a grid one cell thick.
    let quad = TriangleMesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        triangles: vec![
            [0, 1, 2],
            [0, 2, 3],
            [0, 1, 2],
            [0, 2, 3],
            [0, 1, 2],
            [0, 2, 3],
        ],
        normals: Vec::new(),
        texcoords: Vec::new(),
        cutout: None,
    };
    let grid = GridIntersector::build(&[world(Shape::Mesh(quad))], None);
    assert_eq!(grid.spec().unwrap().resolution[2], 1);
    let hit = grid
        .intersect(&Ray::new(Vec3::new(0.5, 0.5, 1.0), -Vec3::Z))
        .unwrap();
    assert_eq!(hit.t, 1.0);
    let along = Ray::new(Vec3::new(-1.0, 0.5, 0.0), Vec3::X);
    assert!(grid.intersect(&along).is_none());
}

#[test]
fn accelerator_builds_the_grid_backend_with_planes_and_packets() {
    let objects = vec![
        world(Shape::Plane(Plane {
            point: Vec3::new(0.0, -1.0, 0.0),
            normal: Vec3::Y,
        })),
        world(sphere(Vec3::new(0.0, 0.0, -5.0), 1.0)),
        world(Shape::Mesh(cube(2, Vec3::new(3.0, 0.0, -5.0), 0.5))),
    ];
    let accel = Accelerator::build(BackendKind::Grid, &objects).unwrap();
    assert_eq!(accel.kind(), BackendKind::Grid);
    let hit = accel.intersect(&Ray::new(Vec3::ZERO, -Vec3::Z)).unwrap();
    assert_eq!((hit.object, hit.prim), (1, 0));
    assert!((hit.t - 4.0).abs() < 1e-6);
    let hit = accel.intersect(&Ray::new(Vec3::ZERO, -Vec3::Y)).unwrap();
    assert_eq!(hit.object, 0);
    let hit = accel
        .intersect(&Ray::new(Vec3::ZERO, Vec3::new(3.0, 0.0, -5.0)))
        .unwrap();
    assert_eq!(hit.object, 2);

    let grid = GridIntersector::build(&objects, None);
    let rays: RayPacket =
        std::array::from_fn(|i| Ray::new(Vec3::ZERO, Vec3::new(i as f32 - 3.0, 0.1, -5.0)));
    let mask = 0b1101_0111;
    let mut hits: HitPacket = [None; PACKET_WIDTH];
    grid.intersect8(&rays, mask, &mut hits);
    let occluded = grid.occluded8(&rays, mask);
    for lane in 0..PACKET_WIDTH {
        if mask & (1 << lane) != 0 {
            assert_eq!(hits[lane], grid.intersect(&rays[lane]));
            assert_eq!(occluded & (1 << lane) != 0, grid.occluded(&rays[lane]));
        } else {
            assert_eq!(hits[lane], None);
        }
    }
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<GridIntersector>();
}
