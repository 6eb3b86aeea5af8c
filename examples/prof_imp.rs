//! scratch
use rapier3d_mpc184::prelude::*;
use rapier3d_mpc184::studies::benchmarks;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let arms: usize = a[1].parse().unwrap();
    let steps: usize = a[2].parse().unwrap();
    let mode = a[3].as_str();
    let (backend, outputs) = match mode {
        "lf" => (Backend::Lagrange, Outputs::Full),
        "if" => (Backend::RapierImpulse, Outputs::Full),
        _ => (Backend::RapierImpulse, Outputs::Kinematics),
    };
    let s = WorldSettings { dt: 1.0 / 60.0, substeps: 4, backend, outputs, ..Default::default() };
    let mut b = benchmarks::mixed(s, arms).unwrap();
    if mode.starts_with("alone") { benchmarks::rapier_alone(&mut b.world); }
    for _ in 0..10 { if mode.starts_with("alone") { b.world.physics.step() } else { b.world.step().unwrap() } }
    let t = std::time::Instant::now();
    for _ in 0..steps { if mode.starts_with("alone") { b.world.physics.step() } else { b.world.step().unwrap() } }
    let us = t.elapsed().as_secs_f64() * 1e6 / steps as f64;
    println!("{us:.1} us/step");
}
