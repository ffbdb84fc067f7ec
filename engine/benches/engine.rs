//! Engine throughput on the paper config: random actions, `symbol_onehot` u8 written every
//! step, 500-step episodes with resets included. Throughput elements = steps.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rogue_gym_engine::{
    Action, Dtype, Encoding, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec, splitmix64,
};
use std::hint::black_box;

const STEPS: u64 = 100_000;

fn run(
    game: &mut Game,
    spec: &ObsSpec,
    buf_u8: &mut [u8],
    buf_f32: &mut [f32],
    state: &mut u64,
    episode: &mut u64,
) {
    for _ in 0..STEPS {
        *state = splitmix64(*state);
        let a = Action::ALL[(*state % 11) as usize];
        let r = game.step(a);
        let out = match spec.dtype {
            Dtype::U8 => ObsBufMut::U8(buf_u8),
            Dtype::F32 => ObsBufMut::F32(buf_f32),
        };
        game.write_obs(spec, out).expect("obs");
        if r.terminated || r.truncated {
            *episode += 1;
            game.reset(*episode % 40);
        }
    }
    black_box(&buf_u8);
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("engine");
    group.throughput(Throughput::Elements(STEPS));
    group.sample_size(20);
    for (name, cfg, encoding, dtype) in [
        (
            "paper/symbol_onehot_u8",
            GameConfig::paper(),
            Encoding::SymbolOnehot,
            Dtype::U8,
        ),
        (
            "paper/symbol_index_u8",
            GameConfig::paper(),
            Encoding::SymbolIndex,
            Dtype::U8,
        ),
        (
            "paper/symbol_onehot_f32",
            GameConfig::paper(),
            Encoding::SymbolOnehot,
            Dtype::F32,
        ),
        (
            "default_80x24/symbol_onehot_u8",
            GameConfig::default(),
            Encoding::SymbolOnehot,
            Dtype::U8,
        ),
    ] {
        let mut game = Game::new(
            &cfg,
            EpisodeConfig {
                max_steps: 500,
                stair_reward: 50.0,
            },
        )
        .expect("config");
        let spec = ObsSpec {
            encoding,
            dtype,
            ..ObsSpec::paper()
        };
        let n: usize = game.observation_shape(&spec).iter().product();
        let mut buf_u8 = vec![0u8; n];
        let mut buf_f32 = vec![0f32; n];
        let (mut state, mut episode) = (1u64, 0u64);
        group.bench_function(name, |b| {
            b.iter(|| {
                run(
                    &mut game,
                    &spec,
                    &mut buf_u8,
                    &mut buf_f32,
                    &mut state,
                    &mut episode,
                )
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
