//! Deterministic random streams: ChaCha8 seeded from `(seed, stream, index)` through splitmix64,
//! so each subsystem (dungeon of floor k, items of floor k, monsters of floor k, play) has its
//! own independent stream. [`xorshift`] is the original's generator, for `"seeding": "original"`.

pub(crate) mod xorshift;

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng as _, SeedableRng};

/// The splitmix64 finaliser: a bijective 64-bit mixing function.
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Stream identifiers.
#[derive(Debug, Clone, Copy)]
#[repr(u64)]
pub(crate) enum Stream {
    /// Layout of one floor (index = floor number).
    Dungeon = 0x6475_6e67_656f_6e00,
    /// Gold rolls of one floor.
    Items = 0x6974_656d_7300_0000,
    /// Monster placement of one floor.
    Enemies = 0x656e_656d_6965_7300,
    /// Everything decided during play (search, combat, monster moves, healing).
    Play = 0x706c_6179_0000_0000,
}

/// A seeded random stream with the few draws the game needs.
#[derive(Debug, Clone)]
pub(crate) struct GameRng(ChaCha8Rng);

impl GameRng {
    /// The stream `stream` number `index` of `seed`.
    pub fn new(seed: u64, stream: Stream, index: u64) -> Self {
        let s = splitmix64(splitmix64(seed ^ stream as u64).wrapping_add(index));
        GameRng(ChaCha8Rng::seed_from_u64(s))
    }

    /// Uniform in `[0, n)`; 0 when `n == 0`. Unbiased (Lemire's multiply-and-reject).
    pub fn below(&mut self, n: u32) -> u32 {
        if n <= 1 {
            return 0;
        }
        let threshold = n.wrapping_neg() % n;
        loop {
            let m = u64::from(self.0.next_u32()) * u64::from(n);
            if (m as u32) >= threshold {
                return (m >> 32) as u32;
            }
        }
    }

    /// Uniform in `[lo, hi)`; `lo` when the range is empty.
    pub fn range(&mut self, lo: i32, hi: i32) -> i32 {
        if hi <= lo {
            return lo;
        }
        lo + self.below((hi - lo) as u32) as i32
    }

    /// True with probability `1/inv` (`inv` >= 1).
    pub fn one_in(&mut self, inv: u32) -> bool {
        self.below(inv.max(1)) == 0
    }

    /// True with probability `percent/100`.
    pub fn percent(&mut self, percent: u32) -> bool {
        self.below(100) < percent
    }

    /// Sum of `times` rolls of 1..=`max`.
    pub fn dice(&mut self, times: u32, max: u32) -> i32 {
        (0..times).map(|_| self.below(max) as i32 + 1).sum::<i32>() * i32::from(max > 0)
    }
}
