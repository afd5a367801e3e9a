//! The grid against Embree on the same scenes and rays: a paper-like
//! scene with a bumpy mesh and instances, and the timing of both.

use super::*;

/// A test scene like the paper's plus a bumpy mesh: 19 spheres, 12
/// polygons (quads as two triangles), one mesh, one instanced sphere and one
/// instanced mesh.
fn comparison_scene(mesh: TriangleMesh, mesh_scale: f32) -> Vec<Object> {
    let mut rng = Rng::new(2024);
    let mut objects = Vec::new();
    let mesh_bounds = mesh.bounds();
    let fit = Affine3A::from_scale(Vec3::splat(mesh_scale / mesh_bounds.extent().max_element()))
        * Affine3A::from_translation(-mesh_bounds.center());
    objects.push(world(baked(&Shape::Mesh(mesh.clone()), &fit)));
    for _ in 0..19 {
        let c = rng.vec_in(Vec3::new(-6.0, -1.0, -12.0), Vec3::new(6.0, 3.0, -3.0));
        objects.push(world(sphere(c, rng.range(0.2, 1.0))));
    }
    for _ in 0..12 {
        let c = rng.vec_in(Vec3::new(-8.0, -1.0, -14.0), Vec3::new(8.0, 4.0, -2.0));
        let (u, v) = (
            rng.unit_vector() * rng.range(0.5, 2.0),
            rng.unit_vector() * rng.range(0.5, 2.0),
        );
        let quad = TriangleMesh {
            positions: vec![c - u - v, c + u - v, c + u + v, c - u + v],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            normals: Vec::new(),
            texcoords: Vec::new(),
            cutout: None,
        };
        objects.push(world(Shape::Mesh(quad)));
    }
    objects.push(object(
        sphere(Vec3::ZERO, 1.0),
        Placement::Instance(
            Affine3A::from_translation(Vec3::new(2.0, -0.5, -4.0))
                * Affine3A::from_scale(Vec3::splat(0.5)),
        ),
    ));
    objects.push(object(
        Shape::Mesh(mesh),
        Placement::Instance(
            Affine3A::from_translation(Vec3::new(-3.0, 1.0, -7.0))
                * Affine3A::from_rotation_y(0.8)
                * Affine3A::from_scale(Vec3::splat(0.6))
                * fit,
        ),
    ));
    objects
}

#[test]
fn agrees_with_embree_on_a_bumpy_mesh_and_spheres() {
    let objects = comparison_scene(blob(4, 99), 3.0);
    let embree = EmbreeIntersector::build(&objects).unwrap();
    let grid = GridIntersector::build(&objects, None);
    let mut rng = Rng::new(1234);
    let rays = 20_000;
    let (mut hits, mut disagreements, mut same_triangle) = (0, 0, 0);
    for i in 0..rays {
        let o = if i % 2 == 0 {
            Vec3::new(0.0, 1.0, 4.0) + rng.vec_in(Vec3::splat(-1.0), Vec3::ONE)
        } else {
            rng.vec_in(Vec3::new(-8.0, -2.0, -15.0), Vec3::new(8.0, 5.0, 0.0))
        };
        let target = rng.vec_in(Vec3::new(-6.0, -1.0, -12.0), Vec3::new(6.0, 3.0, -1.0));
        let ray = Ray::new(o, target - o);
        let (g, e) = (grid.intersect(&ray), embree.intersect(&ray));
        assert_eq!(grid.occluded(&ray), g.is_some());
        match (g, e) {
            (Some(g), Some(e)) => {
                hits += 1;
                let close = same_distance(&ray, g.t, e.t);
                if !close || g.object != e.object {
                    disagreements += 1;
                    assert!(close, "t differs: grid {g:?} embree {e:?} for {ray:?}");
                }
                let mesh = matches!(objects[e.object as usize].shape, Shape::Mesh(_));
                if mesh && (g.object, g.prim) == (e.object, e.prim) {
                    // Same barycentric convention as Embree (loose: grazing
                    // hits on small triangles move them apart a little).
                    assert!(
                        (g.u - e.u).abs() < 1e-2 && (g.v - e.v).abs() < 1e-2,
                        "barycentrics differ: grid {g:?} embree {e:?}"
                    );
                    same_triangle += 1;
                }
            }
            (None, None) => {}
            (g, e) => {
                // A hit one backend reports and the other does not must
                // graze a triangle edge (or a sphere's silhouette, where
                // Embree's f32 test and our f64 one may round apart).
                disagreements += 1;
                let h = g.or(e).unwrap();
                let is_sphere = objects[h.object as usize]
                    .shape
                    .bounds()
                    .extent()
                    .min_element()
                    > 0.0
                    && matches!(objects[h.object as usize].shape, Shape::Sphere(_));
                let edge = h.u.min(h.v).min(1.0 - h.u - h.v) < 1e-4;
                assert!(edge || is_sphere, "grid {g:?} embree {e:?} for {ray:?}");
            }
        }
    }
    // The bound: at most 0.05% of the rays (10 of 20,000) may disagree, and
    // only by grazing (checked above).
    assert!(
        disagreements <= rays / 2000,
        "{disagreements} disagreements"
    );
    assert!(hits > rays / 3, "only {hits} hits");
    assert!(
        same_triangle > hits / 3,
        "only {same_triangle} triangle hits"
    );
}

/// Times the grid against Embree on 640x480 primary rays; run with
/// `cargo test --release --lib accel::grid::tests::timing -- --ignored --nocapture`.
#[test]
#[ignore]
fn timing_against_embree() {
    let bunny = load_bunny().unwrap_or_else(|| blob(4, 99));
    for (name, objects) in [
        (
            "paper-like (19 spheres, 12 quads, bumpy blob)",
            comparison_scene(blob(3, 1), 3.0),
        ),
        (
            "bunny (3674 triangles) + paper-like",
            comparison_scene(bunny, 3.0),
        ),
    ] {
        let triangles: usize = objects
            .iter()
            .map(|o| match &o.shape {
                Shape::Mesh(m) => m.triangles.len(),
                _ => 0,
            })
            .sum();
        let start = std::time::Instant::now();
        let grid = GridIntersector::build(&objects, None);
        let build = start.elapsed();
        let embree = EmbreeIntersector::build(&objects).unwrap();
        let (w, h) = (640, 480);
        let eye = Vec3::new(0.0, 1.0, 4.0);
        let rays: Vec<Ray> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let dir = Vec3::new(
                    (x - w as f32 / 2.0) / 400.0,
                    -(y - h as f32 / 2.0) / 400.0,
                    -1.0,
                );
                Ray::new(eye, dir)
            })
            .collect();
        let time = |f: &dyn Fn(&Ray) -> Option<Hit>| {
            let mut best = f64::INFINITY;
            let mut count = 0;
            for _ in 0..5 {
                let start = std::time::Instant::now();
                count = rays.iter().filter(|r| f(r).is_some()).count();
                best = best.min(start.elapsed().as_secs_f64());
            }
            (best, count)
        };
        let (tg, ng) = time(&|r| grid.intersect(r));
        let (te, ne) = time(&|r| embree.intersect(r));
        let packets: Vec<RayPacket> = rays
            .chunks(8)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect();
        let mut te8 = f64::INFINITY;
        for _ in 0..5 {
            let start = std::time::Instant::now();
            let mut hits: HitPacket = [None; PACKET_WIDTH];
            for p in &packets {
                embree.intersect8(p, 0xff, &mut hits);
                std::hint::black_box(&hits);
            }
            te8 = te8.min(start.elapsed().as_secs_f64());
        }
        println!(
            "{name}: {triangles} triangles, grid {:?} ({} refs, built in {build:?})\n  grid {:.1} ms ({ng} hits), embree {:.1} ms ({ne} hits), embree x8 {:.1} ms: grid / embree = {:.2}",
            grid.spec().map(|s| s.resolution),
            grid.references(),
            tg * 1e3,
            te * 1e3,
            te8 * 1e3,
            tg / te
        );
    }
}

/// The Stanford bunny from the shared data folder, if it is there.
fn load_bunny() -> Option<TriangleMesh> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/bunny.obj");
    let text = std::fs::read_to_string(path).ok()?;
    let mut mesh = TriangleMesh::default();
    for line in text.lines() {
        let mut parts = line.split_whitespace();
        match parts.next() {
            Some("v") => {
                let v: Vec<f32> = parts.take(3).filter_map(|x| x.parse().ok()).collect();
                mesh.positions.push(Vec3::new(v[0], v[1], v[2]));
            }
            Some("f") => {
                let idx: Vec<u32> = parts
                    .filter_map(|x| x.split('/').next()?.parse::<u32>().ok())
                    .map(|i| i - 1)
                    .collect();
                for k in 1..idx.len() - 1 {
                    mesh.triangles.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Some(mesh)
}
