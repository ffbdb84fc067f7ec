//! What checking a sync step's actions costs the caller, per batch: `validate_actions` runs
//! once per `step()` over every env's action before any worker is sent its block, so it is
//! part of the caller's own time that grows with the batch (benchmarks/scaling.py --model).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use rogue_gym_pool::validate_actions;
use std::hint::black_box;

fn actions(c: &mut Criterion) {
    let mut g = c.benchmark_group("validate_actions");
    for n in [64usize, 1024, 4096] {
        let acts: Vec<i64> = (0..n as i64).map(|i| (i * 7) % 11).collect();
        g.bench_with_input(BenchmarkId::from_parameter(n), &acts, |b, a| {
            b.iter(|| validate_actions(black_box(a), 0..a.len(), black_box(11)))
        });
    }
    g.finish();
}

criterion_group!(benches, actions);
criterion_main!(benches);
