//! Micro-benchmarks of the solver's phases on synthetic graphs (no files
//! needed): the one-off setup (Hessian structure and symbolic analysis), one
//! Gauss-Newton iteration (linearise, assemble, factorise, solve, update, χ²),
//! a χ² evaluation, and reading and writing the graph as g2o text. `cargo bench`; the suite against the peers is
//! `scripts/bench.py` (see BENCHMARKS.md).

use cairn::core::Graph;
use cairn::generate::{ManhattanOptions, SphereOptions, manhattan, sphere};
use cairn::solvers::{Algorithm, Optimizer, SolverConfig};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn graphs() -> Vec<(&'static str, Graph)> {
    let m = manhattan(&ManhattanOptions {
        poses: 10_000,
        size: 60,
        ..Default::default()
    })
    .expect("the generator makes a valid graph");
    let s = sphere(&SphereOptions {
        rings: 50,
        poses_per_ring: 50,
        ..Default::default()
    })
    .expect("the generator makes a valid graph");
    vec![("manhattan-10k", m), ("sphere-2500", s)]
}

fn one_iteration() -> SolverConfig {
    SolverConfig {
        algorithm: Algorithm::GaussNewton,
        max_iterations: 1,
        ..Default::default()
    }
}

fn phases(c: &mut Criterion) {
    // One thread, as the suite runs every library. Building the global pool
    // fails only if it exists already, and then it is used as it is.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    for (name, mut graph) in graphs() {
        let mut group = c.benchmark_group(name);
        group.sample_size(20);
        group.bench_function("setup", |b| {
            b.iter(|| Optimizer::new(black_box(&graph), one_iteration()).map(|_| ()))
        });
        let mut optimizer = Optimizer::new(&graph, one_iteration()).expect("setup");
        let start = graph.values().params().to_vec();
        group.bench_function("gn_iteration", |b| {
            b.iter(|| {
                graph.values_mut().params_mut().copy_from_slice(&start);
                optimizer.optimize(&mut graph).map(|s| s.final_chi2)
            })
        });
        group.bench_function("chi2", |b| b.iter(|| black_box(&graph).chi2()));
        let text = cairn::g2o::to_string(&graph).expect("the graph writes");
        group.bench_function("read_g2o", |b| {
            b.iter(|| cairn::g2o::read_bytes(black_box(text.as_bytes()), &Default::default()))
        });
        group.bench_function("write_g2o", |b| {
            b.iter(|| cairn::g2o::to_string(black_box(&graph)))
        });
        group.finish();
    }
}

criterion_group!(benches, phases);
criterion_main!(benches);
