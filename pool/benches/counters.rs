//! What the live statistics cost per `step()`, from the primitives they are made of: a worker
//! serving one command reads the clock 6 times (3 stamps, 3 elapsed) and makes 5 relaxed
//! atomic adds (`stats.rs`, `worker.rs`); the caller's `CallClock` reads it twice and makes 3
//! adds per call (`python/src/clock.rs`). `per_step` does all of them once: compare it with the
//! time of one `step()` of the pool (docs/performance.md gives both).

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Clock reads per step: the worker's 6 and the caller's 2.
const CLOCK_READS: usize = 8;
/// Relaxed atomic adds per step: the worker's 5 and the caller's 3.
const ADDS: usize = 8;

fn counters(c: &mut Criterion) {
    let row: Vec<AtomicU64> = (0..8).map(|_| AtomicU64::new(0)).collect();
    let epoch = Instant::now();
    let mut g = c.benchmark_group("counters");
    g.bench_function("clock_read", |b| {
        b.iter(|| black_box(epoch.elapsed().as_nanos() as u64))
    });
    g.bench_function("relaxed_add", |b| {
        b.iter(|| row[black_box(3)].fetch_add(black_box(7), Ordering::Relaxed))
    });
    g.bench_function("per_step", |b| {
        b.iter(|| {
            for k in 0..CLOCK_READS.max(ADDS) {
                let t = if k < CLOCK_READS {
                    epoch.elapsed().as_nanos() as u64
                } else {
                    0
                };
                if k < ADDS {
                    row[k % 8].fetch_add(black_box(t), Ordering::Relaxed);
                }
            }
        })
    });
    g.finish();
}

criterion_group!(benches, counters);
criterion_main!(benches);
