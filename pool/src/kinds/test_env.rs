//! A small deterministic env for tests and benchmarks of the pool itself.

use serde_json::Value;

use crate::env::{Dtype, Env, EnvError, EnvSpec, StepOutcome, bytes_as_f32_mut};
use crate::seeds::splitmix;

/// A deterministic toy env: its state is a 64-bit hash of (seed, actions so far). Rewards,
/// termination and every observation byte derive from the state, so any divergence in seeds or
/// actions shows in the trajectory.
///
/// JSON spec (all fields optional): `{"kind": "test", "obs_shape": [4, 8, 8], "dtype": "u8",
/// "num_actions": 5, "max_steps": 50, "work": 0, "fail_on_action": null}`. `work` adds that
/// many mixing rounds per step (simulated compute). `fail_on_action` makes `step` return an
/// error for that action (fault injection). It takes action extras (kept until the next one;
/// `b"bad"` is refused) and answers the calls `t` (its step count) and `x` (its last extra).
#[derive(Debug, Clone)]
pub struct TestEnv {
    spec: EnvSpec,
    max_steps: u32,
    work: u32,
    fail_on_action: Option<usize>,
    state: u64,
    t: u32,
    extra: Vec<u8>,
}

fn get_u64(v: &Value, key: &str, default: u64) -> Result<u64, EnvError> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(default),
        Some(x) => x.as_u64().ok_or_else(|| {
            EnvError::new(format!(
                "test env: {key:?} must be a non-negative integer, got {x}"
            ))
        }),
    }
}

impl TestEnv {
    /// Build from a JSON spec (see the type docs).
    pub fn from_json(v: &Value) -> Result<TestEnv, EnvError> {
        let obs_shape = match v.get("obs_shape") {
            None | Some(Value::Null) => vec![4, 8, 8],
            Some(Value::Array(a)) => a
                .iter()
                .map(|x| x.as_u64().map(|n| n as usize))
                .collect::<Option<Vec<_>>>()
                .ok_or_else(|| EnvError::new("test env: obs_shape must be a list of integers"))?,
            Some(x) => {
                return Err(EnvError::new(format!(
                    "test env: obs_shape must be a list, got {x}"
                )));
            }
        };
        let dtype = match v.get("dtype").and_then(Value::as_str) {
            None | Some("u8") | Some("uint8") => Dtype::U8,
            Some("f32") | Some("float32") => Dtype::F32,
            Some(x) => {
                return Err(EnvError::new(format!(
                    "test env: dtype must be \"u8\" or \"f32\", got {x:?}"
                )));
            }
        };
        let fail_on_action = match v.get("fail_on_action") {
            None | Some(Value::Null) => None,
            Some(_) => Some(get_u64(v, "fail_on_action", 0)? as usize),
        };
        Ok(TestEnv {
            spec: EnvSpec {
                obs_shape,
                dtype,
                num_actions: get_u64(v, "num_actions", 5)? as usize,
                info_names: vec!["t".into(), "state_mod_1000".into()],
                action_bytes: 0,
                extra_bytes: 0,
                flag_infos: Vec::new(),
            },
            max_steps: get_u64(v, "max_steps", 50)? as u32,
            work: get_u64(v, "work", 0)? as u32,
            fail_on_action,
            state: 0,
            t: 0,
            extra: Vec::new(),
        })
    }

    fn write_obs(&self, obs: &mut [u8]) -> Result<(), EnvError> {
        let s = self.state;
        match self.spec.dtype {
            Dtype::U8 => {
                for (k, b) in obs.iter_mut().enumerate() {
                    *b = ((s >> ((k & 7) * 8)) as u8) ^ (k as u8);
                }
            }
            Dtype::F32 => {
                let f = bytes_as_f32_mut(obs)?;
                for (k, x) in f.iter_mut().enumerate() {
                    *x = (((s >> ((k & 7) * 8)) as u8) ^ (k as u8)) as f32 / 255.0;
                }
            }
        }
        Ok(())
    }
}

/// [`crate::EnvCtor`] of the `"test"` kind.
pub fn make_test_env(v: &Value, _index: u64) -> Result<Box<dyn Env>, EnvError> {
    Ok(Box::new(TestEnv::from_json(v)?))
}

impl Env for TestEnv {
    fn spec(&self) -> EnvSpec {
        self.spec.clone()
    }

    fn reset(&mut self, seed: u64, obs: &mut [u8]) -> Result<(), EnvError> {
        self.state = splitmix(seed);
        self.t = 0;
        self.write_obs(obs)
    }

    fn step(&mut self, action: usize, obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        if Some(action) == self.fail_on_action {
            return Err(EnvError::new(format!(
                "test env: injected failure on action {action}"
            )));
        }
        let mut s = splitmix(self.state ^ (action as u64 + 1).wrapping_mul(0x1000_0001));
        for _ in 0..self.work {
            s = splitmix(s);
        }
        self.state = s;
        self.t += 1;
        self.write_obs(obs)?;
        Ok(StepOutcome {
            reward: (s % 7) as f64 - 3.0,
            terminated: s.is_multiple_of(31),
            truncated: self.t >= self.max_steps,
        })
    }

    fn observe(&self, obs: &mut [u8]) -> Result<(), EnvError> {
        self.write_obs(obs)
    }

    /// Calls: `b"t"` answers the episode's step count (u32, little endian).
    fn set_action_extra(&mut self, extra: &[u8]) -> Result<(), EnvError> {
        if extra == b"bad" {
            return Err(EnvError::new("test env: a bad action extra"));
        }
        self.extra = extra.to_vec();
        Ok(())
    }

    fn call(&mut self, request: &[u8]) -> Result<Vec<u8>, EnvError> {
        match request {
            b"t" => Ok(self.t.to_le_bytes().to_vec()),
            b"x" => Ok(self.extra.clone()),
            other => Err(EnvError::new(format!(
                "test env: unknown call {:?}",
                String::from_utf8_lossy(other)
            ))),
        }
    }

    fn info(&self, out: &mut [f64]) {
        if let [t, m, ..] = out {
            *t = f64::from(self.t);
            *m = (self.state % 1000) as f64;
        }
    }
}
