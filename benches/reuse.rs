//! Hot paths of the reuse algorithms: the pan shift (a frame assembled
//! from an already traced buffer), RSVP's batch tracing of scattered null
//! samples, RSVP's resampling of a viewport from a traced buffer, the bare voxel walk, OSTC's recording of rays into voxel bits
//! (walk plus marking), and the merging of dirty regions when an object
//! moves.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use glam::Vec3;
use retrace::accel::{Accelerator, BackendKind};
use retrace::camera::{Camera, Projection};
use retrace::camera::{ViewTransform, ViewportPose};
use retrace::geometry::Aabb;
use retrace::ray::{Ray, PACKET_WIDTH};
use retrace::render::{trace_groups, SampleGroup};
use retrace::reuse::lattice_buffer::LatticeBuffer;
use retrace::reuse::ostc::{Footprint, Ostc, DEFAULT_VOXELS};
use retrace::reuse::pan::EqualAngleLattice;
use retrace::reuse::regions::{RegionGrid, RegionSet};
use retrace::reuse::rsvp::{Level, LevelRays, RsvpKnobs, SampleBuffer, SampleLattice};
use retrace::rng::SplitMix64;
use retrace::sampling::PixelSamples;
use retrace::scene::{paper_scene, SceneOverrides};
use retrace::shade::{RayKind, RayObserver, Shader};

fn pan_shift(c: &mut Criterion) {
    let scene = paper_scene(&SceneOverrides::default()).expect("built-in scene loads");
    let accel = Accelerator::build(BackendKind::Embree, &scene.objects).expect("backend builds");
    let shader = Shader::new(&scene, &accel);
    let lattice = EqualAngleLattice::for_camera(&scene.camera);
    let window = lattice.window(&scene.camera);
    let mut buffer = LatticeBuffer::new(lattice, window.row..window.row + 480, false);
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
    let layout = retrace::reuse::regions::RegionLayout::new(
        RegionGrid(16).region_size(640, 480),
        2304,
        0,
        482,
    );
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
    let record = |ostc: &Ostc| {
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
    };
    let mut group = c.benchmark_group("ostc");
    // Each run into fresh bookkeeping: regions keep their recorded
    // segments until forgotten, so one shared `Ostc` would grow.
    group.bench_function("record 4096 packets (8 rays, to the exit)", |b| {
        b.iter_batched_ref(
            || ostc_fixture().0,
            |fresh| record(fresh),
            BatchSize::LargeInput,
        )
    });
    record(&ostc);
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

/// The level-0 sample groups of the RSVP buffer that the paper camera's
/// 640x480 view covers.
fn groups_in_view(scene: &retrace::scene::Scene, lattice: &SampleLattice) -> Vec<SampleGroup> {
    let pose = ViewportPose::new(scene.camera.clone(), ViewTransform::default());
    let (w, h) = (
        f64::from(scene.camera.width),
        f64::from(scene.camera.height),
    );
    let (mut cols, mut rows) = ((f64::MAX, f64::MIN), (f64::MAX, f64::MIN));
    for (x, y) in [
        (0.0, 0.0),
        (w, 0.0),
        (0.0, h),
        (w, h),
        (w / 2.0, 0.0),
        (w / 2.0, h),
    ] {
        let (col, row) = lattice
            .viewport_coords(&pose, glam::DVec2::new(x, y))
            .expect("the view's corners look somewhere");
        cols = (cols.0.min(col), cols.1.max(col));
        rows = (rows.0.min(row), rows.1.max(row));
    }
    SampleGroup::covering(
        cols.0.floor() as i64..cols.1.ceil() as i64,
        rows.0.floor() as i64..rows.1.ceil() as i64,
    )
}

/// RSVP traces the null samples viewports touch in one parallel batch.
/// After OSTC erasures or a zoom, those are scattered over the view. A
/// random 5% of the view's groups is a fair sample of its content, so its
/// rate (groups per second) against the whole view's shows what the
/// scattering costs in coherence and batch overhead.
fn rsvp_null_batches(c: &mut Criterion) {
    let scene = paper_scene(&SceneOverrides::default()).expect("built-in scene loads");
    let accel = Accelerator::build(BackendKind::Embree, &scene.objects).expect("backend builds");
    let shader = Shader::new(&scene, &accel);
    let lattice = SampleLattice::for_camera(&scene.camera);
    let source = LevelRays {
        lattice: &lattice,
        level: Level::default(),
    };
    let view = groups_in_view(&scene, &lattice);
    // In the order the buffer traces a batch: by row, then column.
    let mut rng = SplitMix64(11);
    let scattered: Vec<SampleGroup> = view
        .iter()
        .copied()
        .filter(|_| rng.next_u64() % 20 == 0)
        .collect();
    let mut group = c.benchmark_group("rsvp batch of null groups, paper 640x480 view");
    group.throughput(Throughput::Elements(scattered.len() as u64));
    group.bench_function(format!("{} scattered (5%)", scattered.len()), |b| {
        b.iter(|| trace_groups(&shader, &source, &scattered))
    });
    group.throughput(Throughput::Elements(view.len() as u64));
    group.sample_size(20);
    group.bench_function(format!("{} (the whole view)", view.len()), |b| {
        b.iter(|| trace_groups(&shader, &source, &view))
    });
    group.finish();
}

/// A steady RSVP frame: E2's 640x480 perspective viewport at both ends of
/// its zoom, resampled from a buffer that already holds every sample it
/// reads (pass 1's mapping and pass 2's gather, nothing traced). Besides
/// its few new samples, this is what each later frame of E2 pays, timed
/// far more steadily than one run of `retrace bench` can. At 4 and 16
/// samples a pixel, the pixel box at the density `RsvpStore` reads it.
fn rsvp_resample(c: &mut Criterion) {
    let scene = paper_scene(&SceneOverrides::default()).expect("built-in scene loads");
    let accel = Accelerator::build(BackendKind::Embree, &scene.objects).expect("backend builds");
    let shader = Shader::new(&scene, &accel);
    let camera = Camera {
        projection: Projection::Perspective,
        fov: 100f64.to_radians(),
        ..scene.camera.clone()
    };
    let mut group = c.benchmark_group("rsvp viewport frame 640x480 from a traced buffer");
    let at = |spp: u32| {
        let samples = PixelSamples::new(spp).expect("a valid count");
        let knobs = RsvpKnobs::default_for(samples);
        RsvpKnobs {
            oversample: knobs.oversample * knobs.density_scale(samples),
            ..knobs
        }
    };
    for (name, zoom, knobs) in [
        ("100 deg (zoom 1)", 1.0, at(1)),
        ("50 deg (zoom 2.56)", 2.5557238, at(1)),
        ("100 deg, pixel box at 4 spp", 1.0, at(4)),
        ("50 deg, pixel box at 4 spp", 2.5557238, at(4)),
        ("100 deg, pixel box at 16 spp", 1.0, at(16)),
    ] {
        let pose = ViewportPose::new(
            camera.clone(),
            ViewTransform {
                zoom,
                ..ViewTransform::default()
            },
        );
        let poses = std::slice::from_ref(&pose);
        let mut buffer = SampleBuffer::new(SampleLattice::for_camera(&scene.camera));
        let first = buffer.render(&shader, poses, &knobs, false, None);
        assert!(first[0].work.samples_traced > 0, "the first frame traces");
        group.bench_function(name, |b| {
            b.iter(|| buffer.render(&shader, poses, &knobs, false, None))
        });
        assert_eq!(
            buffer.render(&shader, poses, &knobs, false, None)[0]
                .work
                .samples_traced,
            0,
            "later frames of the same pose trace nothing"
        );
    }
    group.finish();
}

/// The supercover walk alone over the packets `ostc_recording` records,
/// through a 512-voxel grid: what a finer `--ostc-voxels` adds per ray.
fn voxel_walk(c: &mut Criterion) {
    let (ostc, packets) = ostc_fixture();
    let bounds = ostc.grid().expect("the fixture has a moving object").bounds;
    // The default grid is one voxel, which records without a walk: walk
    // the old default's 512 instead, as `--ostc-voxels 512` would.
    let spec = retrace::voxel::GridSpec::with_cell_budget(bounds, 512.0);
    let mut group = c.benchmark_group("ostc");
    group.bench_function("walk 4096 packets (8 rays, to the exit), no marking", |b| {
        b.iter(|| {
            let mut voxels = 0usize;
            for packet in &packets {
                for ray in packet {
                    voxels += spec.walk(ray.origin, ray.dir, 0.0, f32::INFINITY).count();
                }
            }
            voxels
        })
    });
    group.finish();
}

criterion_group!(
    benches,
    pan_shift,
    rsvp_null_batches,
    rsvp_resample,
    voxel_walk,
    ostc_recording
);
criterion_main!(benches);
