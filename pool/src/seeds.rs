//! The per-env episode-seed schedule.
//!
//! The seed of env `i`'s `e`-th episode is a pure function of (schedule, `i`, `e`, number of
//! envs): never of worker count, batch composition or timing. A pool can also be one shard of
//! a larger set of envs (one pool per machine under Ray): [`Shard`] says which global env
//! indices its envs are, so the shards together play exactly what one big pool would.

/// A splitmix64-style mixer: a bijection on `u64` with good avalanche.
pub fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// `mix(base, env, episode)`: the pseudo-random seed of one episode.
pub fn mix(base: u64, env: u64, episode: u64) -> u64 {
    splitmix(splitmix(base ^ splitmix(env.wrapping_add(0x5EED))) ^ splitmix(episode))
}

/// A set of seeds episodes are drawn from.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SeedSet {
    /// An explicit list (must not be empty).
    List(Vec<u64>),
    /// The half-open range `[start, end)` (must not be empty).
    Range {
        /// First seed.
        start: u64,
        /// One past the last seed.
        end: u64,
    },
}

impl SeedSet {
    /// Number of seeds.
    pub fn len(&self) -> u64 {
        match self {
            SeedSet::List(v) => v.len() as u64,
            SeedSet::Range { start, end } => end.saturating_sub(*start),
        }
    }
    /// Whether the set is empty (an invalid schedule).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The `k`-th seed (`k < len`).
    pub fn get(&self, k: u64) -> u64 {
        match self {
            SeedSet::List(v) => v[k as usize],
            SeedSet::Range { start, .. } => start + k,
        }
    }
}

/// How episodes pick seeds from a [`SeedSet`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SeedPolicy {
    /// `set[mix(base, i, e) % len]`: independent uniform draws (training).
    #[default]
    Sample,
    /// Round robin: `set[(i + e * num_envs) % len]` (evaluation: every seed covered evenly).
    Sequential,
}

/// The episode-seed schedule of a pool.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct SeedSchedule {
    /// Base seed of the pool.
    pub base: u64,
    /// Optional seed set; `None` means `mix(base, i, e)`.
    pub set: Option<SeedSet>,
    /// How episodes draw from `set`.
    #[serde(default)]
    pub policy: SeedPolicy,
    /// Where this pool's envs sit in a larger set (`None`: the pool is the whole set).
    #[serde(default)]
    pub shard: Option<Shard>,
}

/// A pool's envs as a contiguous slice of a larger set of envs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    /// Global index of the pool's env 0.
    pub first_env: u64,
    /// Envs in the whole set.
    pub total_envs: u64,
}

impl SeedSchedule {
    /// Schedule with only a base seed.
    pub fn from_base(base: u64) -> Self {
        SeedSchedule {
            base,
            set: None,
            policy: SeedPolicy::Sample,
            shard: None,
        }
    }
    /// Check the schedule (a set must not be empty) against a pool of `num_envs` envs (a shard
    /// must hold them).
    pub fn validate(&self, num_envs: u64) -> Result<(), String> {
        if let Some(Shard {
            first_env,
            total_envs,
        }) = self.shard
            && first_env
                .checked_add(num_envs)
                .is_none_or(|end| end > total_envs)
        {
            return Err(format!(
                "the shard's envs [{first_env}, {first_env} + {num_envs}) do not fit in its {total_envs} total envs"
            ));
        }
        match &self.set {
            Some(s) if s.is_empty() => Err("the seed set is empty: give at least one seed".into()),
            _ => Ok(()),
        }
    }
    /// Seed of episode `episode` of the pool's env `env` in a pool of `num_envs` envs (with a
    /// shard: of global env `first_env + env` among `total_envs`).
    pub fn seed(&self, env: u64, episode: u64, num_envs: u64) -> u64 {
        let (env, num_envs) = match self.shard {
            Some(s) => (s.first_env.wrapping_add(env), s.total_envs),
            None => (env, num_envs),
        };
        match &self.set {
            None => mix(self.base, env, episode),
            Some(set) => {
                let len = set.len().max(1);
                let k = match self.policy {
                    SeedPolicy::Sample => mix(self.base, env, episode) % len,
                    SeedPolicy::Sequential => {
                        (env.wrapping_add(episode.wrapping_mul(num_envs))) % len
                    }
                };
                set.get(k)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_depend_only_on_env_and_episode() {
        let s = SeedSchedule::from_base(42);
        let a: Vec<u64> = (0..8).map(|i| s.seed(i, 3, 8)).collect();
        // Same values whatever order or grouping they are computed in.
        let b: Vec<u64> = (0..8).rev().map(|i| s.seed(i, 3, 8)).rev().collect();
        assert_eq!(a, b);
        let mut d = a.clone();
        d.sort();
        d.dedup();
        assert_eq!(d.len(), 8, "distinct seeds per env");
        assert_ne!(s.seed(0, 0, 8), s.seed(0, 1, 8));
        assert_ne!(s.seed(0, 0, 8), SeedSchedule::from_base(43).seed(0, 0, 8));
    }

    #[test]
    fn sequential_covers_the_set_evenly() {
        let s = SeedSchedule {
            base: 0,
            set: Some(SeedSet::Range {
                start: 1000,
                end: 1010,
            }),
            policy: SeedPolicy::Sequential,
            shard: None,
        };
        let num_envs = 4;
        let mut counts = [0u32; 10];
        for e in 0..5 {
            for i in 0..num_envs {
                let seed = s.seed(i, e, num_envs);
                assert!((1000..1010).contains(&seed));
                counts[(seed - 1000) as usize] += 1;
            }
        }
        assert_eq!(counts, [2; 10]);
    }

    #[test]
    fn sample_stays_in_the_set() {
        let s = SeedSchedule {
            base: 7,
            set: Some(SeedSet::List(vec![3, 5, 9])),
            policy: SeedPolicy::Sample,
            shard: None,
        };
        let mut seen = std::collections::BTreeSet::new();
        for i in 0..16 {
            for e in 0..16 {
                let x = s.seed(i, e, 16);
                assert!([3, 5, 9].contains(&x));
                seen.insert(x);
            }
        }
        assert_eq!(seen.len(), 3);
        assert!(
            SeedSchedule {
                set: Some(SeedSet::List(vec![])),
                ..s
            }
            .validate(16)
            .is_err()
        );
    }

    #[test]
    fn shards_together_play_the_whole_pools_seeds() {
        for policy in [SeedPolicy::Sample, SeedPolicy::Sequential] {
            let whole = SeedSchedule {
                base: 11,
                set: Some(SeedSet::Range { start: 0, end: 7 }),
                policy,
                shard: None,
            };
            let shard = |first_env| SeedSchedule {
                shard: Some(Shard {
                    first_env,
                    total_envs: 10,
                }),
                ..whole.clone()
            };
            for e in 0..5 {
                let joined: Vec<u64> = (0..4)
                    .map(|i| shard(0).seed(i, e, 4))
                    .chain((0..6).map(|i| shard(4).seed(i, e, 6)))
                    .collect();
                let expected: Vec<u64> = (0..10).map(|i| whole.seed(i, e, 10)).collect();
                assert_eq!(joined, expected, "{policy:?} episode {e}");
            }
        }
        assert!(
            SeedSchedule {
                shard: Some(Shard {
                    first_env: 8,
                    total_envs: 10
                }),
                ..SeedSchedule::default()
            }
            .validate(3)
            .unwrap_err()
            .contains("do not fit")
        );
    }
}
