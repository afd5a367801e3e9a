//! Hot paths of the reuse algorithms: the pan shift (a frame assembled
//! from an already traced buffer), OSTC's recording of rays into voxel
//! bits, and the merging of dirty regions when an object moves.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec3;
use retrace::accel::{Accelerator, BackendKind};
use retrace::geometry::Aabb;
use retrace::ray::{Ray, PACKET_WIDTH};
use retrace::render::SampleGroup;
use retrace::reuse::ostc::{Footprint, Ostc, RegionGrid, RegionSet, DEFAULT_VOXELS};
use retrace::reuse::pan::{EqualAngleLattice, PanBuffer};
use retrace::rng::SplitMix64;
use retrace::scene::{paper_scene, SceneOverrides};
use retrace::shade::{RayKind, RayObserver, Shader};

fn pan_shift(c: &mut Criterion) {
    let scene = paper_scene(&SceneOverrides::default()).expect("built-in scene loads");
    let accel = Accelerator::build(BackendKind::Embree, &scene.objects).expect("backend builds");
    let shader = Shader::new(&scene, &accel);
    let lattice = EqualAngleLattice::for_camera(&scene.camera);
    let window = lattice.window(&scene.camera);
    let mut buffer = PanBuffer::new(lattice, window.row..window.row + 480);
    buffer.frame(&shader, &window, false, None);
    let mut shifted = window;
    shifted.col += 23;
    buffer.frame(&shader, &shifted, false, None);
    let mut group = c.benchmark_group("pan shift 640x480 (traced buffer)");
    group.bench_function("8-bit frame", |b| {
        b.iter(|| buffer.frame(&shader, &shifted, false, None))
    });
    group.bench_function("8-bit + linear frame", |b| {
        b.iter(|| buffer.frame(&shader, &shifted, true, None))
    });
    group.finish();
}

/// An OSTC grid over a 2x4x2 box and packets of rays through and around it.
fn ostc_fixture() -> (Ostc, Vec<[Ray; PACKET_WIDTH]>) {
    let layout =
        retrace::reuse::ostc::RegionLayout::new(RegionGrid(16).region_size(640, 480), 2304, 0, 482);
    let swept = Aabb {
        min: Vec3::new(-1.0, 0.0, -1.0),
        max: Vec3::new(1.0, 4.0, 1.0),
    };
    let ostc = Ostc::new(layout, Some(swept), DEFAULT_VOXELS, &[]);
    let mut rng = SplitMix64(7);
    let packets = (0..4096)
        .map(|_| {
            let origin = Vec3::new(
                rng.range(-8.0, 8.0),
                rng.range(0.0, 6.0),
                rng.range(4.0, 12.0),
            );
            let target = Vec3::new(rng.range(-2.0, 2.0), rng.range(-1.0, 5.0), 0.0);
            std::array::from_fn(|_| {
                let jitter = Vec3::new(rng.range(-0.05, 0.05), rng.range(-0.05, 0.05), 0.0);
                Ray::new(origin, target + jitter - origin)
            })
        })
        .collect();
    (ostc, packets)
}

fn ostc_recording(c: &mut Criterion) {
    let (ostc, packets) = ostc_fixture();
    let ends = [f32::INFINITY; PACKET_WIDTH];
    let mut group = c.benchmark_group("ostc");
    group.bench_function("record 4096 packets (8 rays, to the exit)", |b| {
        b.iter(|| {
            for (i, packet) in packets.iter().enumerate() {
                let group = SampleGroup {
                    col: (i as i64 * 4) % 2304,
                    row: (i as i64 / 576) * 2,
                };
                ostc.marker(group).traced(
                    RayKind::Shadow {
                        light: 0,
                        blocked: 0,
                    },
                    packet,
                    0xff,
                    &ends,
                );
            }
        })
    });
    let ball = |y: f32| Footprint::Ball {
        center: Vec3::new(0.0, y, 0.0),
        radius: 0.5,
    };
    group.bench_function("dirty regions of a moved ball", |b| {
        b.iter(|| ostc.dirty_for(&[ball(1.0), ball(1.2)]))
    });
    let (mut forgetful, _) = ostc_fixture();
    let mut some = RegionSet::empty(forgetful.layout().count());
    for region in (0..forgetful.layout().count()).step_by(17) {
        some.insert(region);
    }
    group.bench_function("forget 1/17 of the regions", |b| {
        b.iter(|| forgetful.forget(&some))
    });
    group.finish();
}

criterion_group!(benches, pan_shift, ostc_recording);
criterion_main!(benches);
