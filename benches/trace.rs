//! Hot paths of a frame: packet tracing of the paper scene through each
//! backend (a full shaded frame), and bare primary-ray packets.

use criterion::{criterion_group, criterion_main, Criterion};
use retrace::accel::{Accelerator, BackendKind, Intersector};
use retrace::camera::RayTable;
use retrace::ray::{Ray, ALL_LANES, PACKET_WIDTH};
use retrace::render::{image_groups, render_frame};
use retrace::scene::{paper_scene, SceneOverrides};

fn paper(width: u32, height: u32) -> retrace::scene::Scene {
    paper_scene(&SceneOverrides {
        width: Some(width),
        height: Some(height),
        ..SceneOverrides::default()
    })
    .expect("built-in scene loads")
}

fn frames(c: &mut Criterion) {
    let scene = paper(320, 240);
    let mut group = c.benchmark_group("paper 320x240 frame");
    group.sample_size(20);
    for backend in [BackendKind::Embree, BackendKind::Grid] {
        let accel = Accelerator::build(backend, &scene.objects).expect("backend builds");
        group.bench_function(backend.to_string(), |b| {
            b.iter(|| render_frame(&scene, &accel))
        });
    }
    group.finish();
}

fn primary_packets(c: &mut Criterion) {
    let scene = paper(320, 240);
    let table = RayTable::new(&scene.camera);
    let packets: Vec<[Ray; PACKET_WIDTH]> = image_groups(320, 240)
        .into_iter()
        .map(|g| {
            g.lane_samples().map(|(x, y)| {
                table
                    .primary_ray(x as u32, y as u32)
                    .expect("inside the image")
            })
        })
        .collect();
    let mut group = c.benchmark_group("paper 320x240 primary packets");
    group.sample_size(20);
    for backend in [BackendKind::Embree, BackendKind::Grid] {
        let accel = Accelerator::build(backend, &scene.objects).expect("backend builds");
        group.bench_function(backend.to_string(), |b| {
            b.iter(|| {
                let mut hits = [None; PACKET_WIDTH];
                for packet in &packets {
                    accel.intersect8(packet, ALL_LANES, &mut hits);
                }
                hits
            })
        });
    }
    group.finish();
}

criterion_group!(benches, frames, primary_packets);
criterion_main!(benches);
