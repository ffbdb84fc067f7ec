//! The Rogue-Gym game as a pool [`Env`] (adapter over `rogue-gym-engine`; the engine knows
//! nothing of the pool).
//!
//! JSON spec of the `"rogue"` kind (every field but `kind` optional):
//! ```json
//! {"kind": "rogue",
//!  "config": { ...game config keys... },      // null/absent: the paper's config
//!  "max_steps": 500, "stair_reward": 50.0,     // EpisodeConfig (engine defaults if absent)
//!  "obs": {"encoding": "symbol_onehot", "dtype": "u8", "status": 0,
//!          "normalize_status": false, "history": false}}   // null/absent: ObsSpec::paper()
//! ```
//! `status` is the original's status bit set (1 dungeon level, 2 hp, 4 max hp, 8 str, 16 max
//! str, 32 defense, 64 player level, 128 exp, 256 hunger; 511 all).

use rogue_gym_engine::{Action, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec, obs};
use serde_json::Value;

use crate::env::{Dtype, Env, EnvError, EnvSpec, StepOutcome, bytes_as_f32_mut};

/// Names of the info values of a Rogue-Gym env, in order.
pub const ROGUE_INFO_NAMES: [&str; 8] = [
    "floor",
    "max_floor",
    "gold",
    "hp",
    "max_hp",
    "steps",
    "died",
    "won",
];

/// The info values of [`ROGUE_INFO_NAMES`] that are flags (0 or 1); the others are counts.
pub const ROGUE_BOOL_INFO: [&str; 2] = ["died", "won"];

/// A Rogue-Gym game with its observation spec.
#[derive(Debug, Clone)]
pub struct RogueEnv {
    game: Game,
    obs: ObsSpec,
    spec: EnvSpec,
}

impl RogueEnv {
    /// Build from a JSON spec (see the module docs).
    pub fn from_json(v: &Value) -> Result<RogueEnv, EnvError> {
        let config = match v.get("config") {
            None | Some(Value::Null) => GameConfig::paper(),
            Some(c) => GameConfig::from_json(&c.to_string())
                .map_err(|e| EnvError::new(format!("rogue env: bad game config: {e}")))?,
        };
        let mut ep = EpisodeConfig::default();
        if let Some(x) = v.get("max_steps").filter(|x| !x.is_null()) {
            ep.max_steps = x
                .as_u64()
                .and_then(|n| u32::try_from(n).ok())
                .ok_or_else(|| EnvError::new(format!("rogue env: bad max_steps {x}")))?;
        }
        if let Some(x) = v.get("stair_reward").filter(|x| !x.is_null()) {
            ep.stair_reward = x
                .as_f64()
                .ok_or_else(|| EnvError::new(format!("rogue env: bad stair_reward {x}")))?
                as f32;
        }
        let obs = ObsSpec::from_json(v.get("obs").unwrap_or(&Value::Null))
            .map_err(|e| EnvError::new(format!("rogue env: {e}")))?;
        let game = Game::new(&config, ep)
            .map_err(|e| EnvError::new(format!("rogue env: bad game config: {e}")))?;
        let spec = EnvSpec {
            obs_shape: game.observation_shape(&obs),
            dtype: match obs.dtype {
                obs::Dtype::U8 => Dtype::U8,
                obs::Dtype::F32 => Dtype::F32,
            },
            num_actions: rogue_gym_engine::NUM_ACTIONS,
            info_names: ROGUE_INFO_NAMES.iter().map(|s| s.to_string()).collect(),
            flag_infos: ROGUE_BOOL_INFO.iter().map(|s| s.to_string()).collect(),
            action_bytes: 0,
            extra_bytes: 0,
        };
        Ok(RogueEnv { game, obs, spec })
    }

    /// The game.
    pub fn game(&self) -> &Game {
        &self.game
    }

    fn write(&self, out: &mut [u8]) -> Result<(), EnvError> {
        let buf = match self.obs.dtype {
            obs::Dtype::U8 => ObsBufMut::U8(out),
            obs::Dtype::F32 => ObsBufMut::F32(bytes_as_f32_mut(out)?),
        };
        self.game
            .write_obs(&self.obs, buf)
            .map_err(|e| EnvError::new(format!("rogue env: observation: {e}")))
    }
}

/// [`crate::EnvCtor`] of the `"rogue"` kind.
pub fn make_rogue_env(v: &Value, _index: u64) -> Result<Box<dyn Env>, EnvError> {
    Ok(Box::new(RogueEnv::from_json(v)?))
}

impl Env for RogueEnv {
    fn spec(&self) -> EnvSpec {
        self.spec.clone()
    }

    fn reset(&mut self, seed: u64, obs: &mut [u8]) -> Result<(), EnvError> {
        self.game.reset(seed);
        self.write(obs)
    }

    fn step(&mut self, action: usize, obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        let a = Action::from_index(action).ok_or_else(|| {
            EnvError::new(format!(
                "rogue env: {}",
                crate::env::action_out_of_range(action, rogue_gym_engine::NUM_ACTIONS)
            ))
        })?;
        let r = self.game.step(a);
        self.write(obs)?;
        Ok(StepOutcome {
            reward: f64::from(r.reward),
            terminated: r.terminated,
            truncated: r.truncated,
        })
    }

    fn observe(&self, obs: &mut [u8]) -> Result<(), EnvError> {
        self.write(obs)
    }

    fn info(&self, out: &mut [f64]) {
        let i = self.game.info();
        let vals = [
            f64::from(i.floor),
            f64::from(i.max_floor),
            f64::from(i.gold),
            f64::from(i.hp),
            f64::from(i.max_hp),
            f64::from(i.steps),
            f64::from(u8::from(i.died)),
            f64::from(u8::from(i.won)),
        ];
        for (o, v) in out.iter_mut().zip(vals) {
            *o = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn paper_spec_and_deterministic_steps() {
        let mut a = RogueEnv::from_json(&json!({"kind": "rogue", "max_steps": 500})).unwrap();
        let s = a.spec();
        assert_eq!(s.obs_shape, vec![17, 16, 32]);
        assert_eq!(s.num_actions, 11);
        let mut b = a.clone();
        let (mut oa, mut ob) = (vec![0u8; s.obs_bytes()], vec![0u8; s.obs_bytes()]);
        a.reset(7, &mut oa).unwrap();
        b.reset(7, &mut ob).unwrap();
        for t in 0..200 {
            let x = a.step(t % 11, &mut oa).unwrap();
            let y = b.step(t % 11, &mut ob).unwrap();
            assert_eq!(x, y);
            assert_eq!(oa, ob);
        }
        assert!(a.step(11, &mut oa).is_err());
    }

    #[test]
    fn f32_obs_and_bad_specs() {
        let mut e = RogueEnv::from_json(
            &json!({"kind": "rogue", "obs": {"dtype": "f32", "status": 511, "history": true}}),
        )
        .unwrap();
        let s = e.spec();
        assert_eq!(s.dtype, Dtype::F32);
        let mut words = vec![0u64; s.obs_bytes().div_ceil(8)];
        let buf = &mut rogue_gym_ipc::words_as_bytes_mut(&mut words)[..s.obs_bytes()];
        e.reset(1, buf).unwrap();
        assert!(RogueEnv::from_json(&json!({"obs": {"colour": 1}})).is_err());
        assert!(RogueEnv::from_json(&json!({"config": {"width": "wide"}})).is_err());
        assert!(RogueEnv::from_json(&json!({"max_steps": -1})).is_err());
    }
}
