//! The per-env episode-seed schedule.
//!
//! The seed of env `i`'s `e`-th episode is a pure function of (schedule, `i`, `e`, number of
//! envs): never of worker count, batch composition or timing.

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
}

impl SeedSchedule {
    /// Schedule with only a base seed.
    pub fn from_base(base: u64) -> Self {
        SeedSchedule {
            base,
            set: None,
            policy: SeedPolicy::Sample,
        }
    }
    /// Check the schedule (a set must not be empty).
    pub fn validate(&self) -> Result<(), String> {
        match &self.set {
            Some(s) if s.is_empty() => Err("the seed set is empty: give at least one seed".into()),
            _ => Ok(()),
        }
    }
    /// Seed of episode `episode` of env `env` in a pool of `num_envs` envs.
    pub fn seed(&self, env: u64, episode: u64, num_envs: u64) -> u64 {
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
            .validate()
            .is_err()
        );
    }
}
