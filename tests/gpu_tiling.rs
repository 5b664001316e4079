//! Grids larger than one storage binding must be processed in tiles. Forcing tiny
//! tiles must give the same field, bit for bit, as one tile.

mod common;
use common::*;
use toolmark::engine::RemovalEngine;
use toolmark::pipeline::prepare_scenes;

#[test]
fn tiled_gpu_removal_equals_untiled() {
    let job = example("convex_sphere.toml");
    let scene = prepare_scenes(&job).remove(0);
    let samples = scene.grid().sample_count() as u64;
    let mut engine = gpu_engine();
    let whole = engine.remove(&scene, &|_, _| {}).expect("one tile");
    // 7 919 samples per tile: not a multiple of the 64-thread workgroup or of a row.
    engine.max_tile_samples = 7_919;
    let tiles = std::sync::Mutex::new(Vec::new());
    let tiled = engine
        .remove(&scene, &|done, total| {
            tiles.lock().unwrap().push((done, total))
        })
        .expect("tiled");
    let tiles = tiles.into_inner().unwrap();
    println!("{samples} samples in {} tiles", tiles.len());
    assert_eq!(tiles.len() as u64, samples.div_ceil(7_919));
    assert_eq!(tiles.last(), Some(&(samples, samples)));
    assert_eq!(whole.pass, tiled.pass);
    assert_eq!(whole.depth_mm, tiled.depth_mm);
}
