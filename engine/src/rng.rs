//! Deterministic random streams: ChaCha8 seeded from `(seed, stream, index)` through splitmix64,
//! so each subsystem (dungeon of floor k, items of floor k, monsters of floor k, play) has its
//! own independent stream.

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
pub(crate) struct GameRng(
    ChaCha8Rng,
    /// Test builds only: the original's raw-seeded XorShift128 (see [`legacy`]).
    #[cfg(test)]
    Option<legacy::XorShift128>,
);

impl GameRng {
    /// The stream `stream` number `index` of `seed`.
    pub fn new(seed: u64, stream: Stream, index: u64) -> Self {
        let s = splitmix64(splitmix64(seed ^ stream as u64).wrapping_add(index));
        GameRng(
            ChaCha8Rng::seed_from_u64(s),
            #[cfg(test)]
            legacy::stream(seed, stream, index),
        )
    }

    /// Uniform in `[0, n)`; 0 when `n == 0`. Unbiased (Lemire's multiply-and-reject).
    pub fn below(&mut self, n: u32) -> u32 {
        if n <= 1 {
            return 0;
        }
        #[cfg(test)]
        if let Some(x) = &mut self.1 {
            return x.below(n);
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

/// Test builds only: a diagnostic emulation of the original's seeding (docs/rules.md §10). The
/// original seeds each of its dungeon, item and enemy XorShift128 streams with the raw seed
/// as the state `(seed_lo, seed_hi, 0, 0)`, without mixing. For small seeds the first outputs
/// are tiny, so floor 1's first draws all come out at the low end of their ranges. With
/// [`legacy::set`], floor 1's dungeon, item and/or monster streams are such a XorShift128
/// with rand 0.7's `gen_range` (every draw taken as a u32 draw); later floors and the play
/// stream stay ours. See `src/tests/random_agent.rs`.
#[cfg(test)]
pub(crate) mod legacy {
    use std::cell::Cell;

    /// Bit of [`set`]'s mask: floor 1's dungeon stream (layout, gold cells, stairs, player).
    pub(crate) const DUNGEON: u8 = 1;
    /// Bit of [`set`]'s mask: floor 1's item stream (gold rolls and amounts).
    pub(crate) const ITEMS: u8 = 2;
    /// Bit of [`set`]'s mask: floor 1's monster stream (placement, kinds, HP).
    pub(crate) const ENEMIES: u8 = 4;
    /// All three.
    pub(crate) const ALL: u8 = DUNGEON | ITEMS | ENEMIES;

    thread_local! {
        static MASK: Cell<u8> = const { Cell::new(0) };
    }

    /// Selects the raw-seeded streams (a mask of [`DUNGEON`], [`ITEMS`], [`ENEMIES`]; 0 =
    /// off) for games built or reset on this thread.
    pub(crate) fn set(mask: u8) {
        MASK.with(|c| c.set(mask));
    }

    /// The legacy stream for `(seed, stream, index)`, if selected and this is floor 1.
    pub(super) fn stream(seed: u64, stream: super::Stream, index: u64) -> Option<XorShift128> {
        let bit = match stream {
            super::Stream::Dungeon => DUNGEON,
            super::Stream::Items => ITEMS,
            super::Stream::Enemies => ENEMIES,
            super::Stream::Play => 0,
        };
        (index == 1 && MASK.with(|c| c.get()) & bit != 0).then(|| XorShift128::from_seed(seed))
    }

    /// Marsaglia's XorShift128 as in rand_xorshift 0.2.
    #[derive(Debug, Clone)]
    pub(crate) struct XorShift128 {
        x: u32,
        y: u32,
        z: u32,
        w: u32,
    }

    impl XorShift128 {
        /// The original's seeding: the seed's little-endian words, all-zero replaced.
        pub(crate) fn from_seed(seed: u64) -> Self {
            let (x, y) = (seed as u32, (seed >> 32) as u32);
            if x == 0 && y == 0 {
                let k = 0x0BAD_5EED;
                return XorShift128 {
                    x: k,
                    y: k,
                    z: k,
                    w: k,
                };
            }
            XorShift128 { x, y, z: 0, w: 0 }
        }

        pub(crate) fn next_u32(&mut self) -> u32 {
            let t = self.x ^ (self.x << 11);
            self.x = self.y;
            self.y = self.z;
            self.z = self.w;
            self.w = self.w ^ (self.w >> 19) ^ t ^ (t >> 8);
            self.w
        }

        /// rand 0.7's `sample_single` for u32: widening multiply, reject above the zone.
        pub(crate) fn below(&mut self, n: u32) -> u32 {
            let zone = (n << n.leading_zeros()).wrapping_sub(1);
            loop {
                let m = u64::from(self.next_u32()) * u64::from(n);
                if (m as u32) <= zone {
                    return (m >> 32) as u32;
                }
            }
        }
    }
}
