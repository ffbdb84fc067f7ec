//! `rogue_gym._native.Game`: one in-process engine game, used by `RogueEnv`.

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rogue_gym_engine::{
    Action, Command, Dtype, EpisodeConfig, Game, GameConfig, NUM_ACTIONS, ObsBufMut, ObsSpec,
};

use crate::spec::parse_spec;

/// One Rogue-Gym game running in this process.
///
/// `Game(config_json, max_steps, stair_reward)`; a bad config raises `ValueError` naming the key.
#[pyclass(module = "rogue_gym._native", name = "Game")]
pub struct PyGame {
    game: Game,
}

fn config_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("invalid Rogue-Gym config: {e}"))
}

impl PyGame {
    fn action(index: i64) -> PyResult<Action> {
        usize::try_from(index)
            .ok()
            .and_then(Action::from_index)
            .ok_or_else(|| {
                PyValueError::new_err(format!(
                    "Invalid action: {index} (expected an int in [0, {NUM_ACTIONS}))"
                ))
            })
    }

    fn shape(&self, spec: &ObsSpec) -> Vec<usize> {
        self.game.observation_shape(spec)
    }
}

#[pymethods]
impl PyGame {
    /// Build a game from a JSON config, a step limit and the reward per new deepest floor.
    #[new]
    fn new(config_json: &str, max_steps: u32, stair_reward: f32) -> PyResult<Self> {
        if max_steps == 0 {
            return Err(PyValueError::new_err("max_steps must be positive"));
        }
        let cfg = GameConfig::from_json(config_json).map_err(config_error)?;
        let game = Game::new(
            &cfg,
            EpisodeConfig {
                max_steps,
                stair_reward,
            },
        )
        .map_err(config_error)?;
        Ok(PyGame { game })
    }

    /// Start a new episode on floor 1 of dungeon `seed`.
    fn reset(&mut self, seed: u64) {
        self.game.reset(seed);
    }

    /// Play action `index` (0..11); returns `(reward, terminated, truncated)`.
    fn step(&mut self, index: i64) -> PyResult<(f32, bool, bool)> {
        let r = self.game.step(Self::action(index)?);
        Ok((r.reward, r.terminated, r.truncated))
    }

    /// Play one key (the 11 action keys, or `HJKLYUBN` to run); returns
    /// `(reward, terminated, truncated)`.
    fn step_key(&mut self, key: char) -> PyResult<(f32, bool, bool)> {
        let cmd = Command::from_key(key).ok_or_else(|| invalid_key(key))?;
        let r = self.game.step_command(cmd);
        Ok((r.reward, r.terminated, r.truncated))
    }

    /// Whether the episode has ended.
    fn is_over(&self) -> bool {
        self.game.is_over()
    }

    /// The observation shape for an observation spec (a `rogue_gym.envs.ObsSpec` tuple).
    fn obs_shape(&self, spec: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
        Ok(self.shape(&parse_spec(spec)?))
    }

    /// The current observation for `spec` as a new numpy array (uint8 or float32).
    fn obs<'py>(&self, py: Python<'py>, spec: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let spec = parse_spec(spec)?;
        let shape = self.shape(&spec);
        let len: usize = shape.iter().product();
        match spec.dtype {
            Dtype::U8 => {
                let mut buf = vec![0u8; len];
                self.game
                    .write_obs(&spec, ObsBufMut::U8(&mut buf))
                    .map_err(|e| PyValueError::new_err(e.to_string()))?;
                Ok(PyArray1::from_vec(py, buf).reshape(shape)?.into_any())
            }
            Dtype::F32 => {
                let mut buf = vec![0f32; len];
                self.game
                    .write_obs(&spec, ObsBufMut::F32(&mut buf))
                    .map_err(|e| PyValueError::new_err(e.to_string()))?;
                Ok(PyArray1::from_vec(py, buf).reshape(shape)?.into_any())
            }
        }
    }

    /// Write the current observation for `spec` into `out` (C-contiguous, right shape and dtype).
    fn write_obs(&self, spec: &Bound<'_, PyAny>, out: &Bound<'_, PyUntypedArray>) -> PyResult<()> {
        let spec = parse_spec(spec)?;
        let shape = self.shape(&spec);
        if out.shape() != shape.as_slice() {
            return Err(PyValueError::new_err(format!(
                "output array has shape {:?}, expected {:?}",
                out.shape(),
                shape
            )));
        }
        let err = |e: rogue_gym_engine::ObsError| PyValueError::new_err(e.to_string());
        match spec.dtype {
            Dtype::U8 => {
                let arr = out
                    .cast::<PyArrayDyn<u8>>()
                    .map_err(|_| wrong_dtype("uint8", out))?;
                let mut rw = arr.try_readwrite()?;
                let slice = rw.as_slice_mut().map_err(|_| not_contiguous())?;
                self.game
                    .write_obs(&spec, ObsBufMut::U8(slice))
                    .map_err(err)
            }
            Dtype::F32 => {
                let arr = out
                    .cast::<PyArrayDyn<f32>>()
                    .map_err(|_| wrong_dtype("float32", out))?;
                let mut rw = arr.try_readwrite()?;
                let slice = rw.as_slice_mut().map_err(|_| not_contiguous())?;
                self.game
                    .write_obs(&spec, ObsBufMut::F32(slice))
                    .map_err(err)
            }
        }
    }

    /// The episode summary: `seed, steps, floor, max_floor, gold, hp, max_hp, died, won`.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let i = self.game.info();
        let d = PyDict::new(py);
        d.set_item("seed", i.seed)?;
        d.set_item("steps", i.steps)?;
        d.set_item("floor", i.floor)?;
        d.set_item("max_floor", i.max_floor)?;
        d.set_item("gold", i.gold)?;
        d.set_item("hp", i.hp)?;
        d.set_item("max_hp", i.max_hp)?;
        d.set_item("died", i.died)?;
        d.set_item("won", i.won)?;
        Ok(d)
    }

    /// The player's status (the original's 9 values plus gold) as a dict.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.game.status();
        let d = PyDict::new(py);
        d.set_item("dungeon_level", s.dungeon_level)?;
        d.set_item("gold", s.gold)?;
        d.set_item("hp_current", s.hp_current)?;
        d.set_item("hp_max", s.hp_max)?;
        d.set_item("str_current", s.str_current)?;
        d.set_item("str_max", s.str_max)?;
        d.set_item("defense", s.defense)?;
        d.set_item("player_level", s.player_level)?;
        d.set_item("exp", s.exp)?;
        d.set_item("hunger", s.hunger)?;
        Ok(d)
    }

    /// The screen rows as strings (rows 0 and height-1 are blank).
    fn screen(&self) -> Vec<String> {
        self.game
            .screen_rows()
            .map(|r| String::from_utf8_lossy(r).into_owned())
            .collect()
    }

    /// The status line in the original's format.
    fn status_line(&self) -> String {
        self.game.status_line()
    }

    /// The last message of the game (empty if none this step).
    fn message(&self) -> String {
        self.game.message().to_string()
    }

    /// The whole config as JSON (every key, defaults included).
    fn config_json(&self) -> String {
        self.game.config().to_json()
    }

    /// Screen width in cells.
    #[getter]
    fn width(&self) -> usize {
        self.game.width()
    }

    /// Screen height in cells.
    #[getter]
    fn height(&self) -> usize {
        self.game.height()
    }

    /// Number of observation symbols (one-hot channels).
    #[getter]
    fn symbols(&self) -> usize {
        self.game.symbol_count()
    }

    /// The player's `(x, y)`.
    fn player_position(&self) -> (i32, i32) {
        self.game.player_position()
    }
}

fn invalid_key(key: char) -> PyErr {
    PyValueError::new_err(format!(
        "Invalid input key: {key:?} (expected one of {:?}, or HJKLYUBN to run)",
        rogue_gym_engine::ACTION_KEYS
    ))
}

fn wrong_dtype(expected: &str, out: &Bound<'_, PyUntypedArray>) -> PyErr {
    PyTypeError::new_err(format!(
        "output array has dtype {}, expected {expected}",
        out.dtype()
    ))
}

fn not_contiguous() -> PyErr {
    PyValueError::new_err("output array must be C-contiguous")
}

/// The action index of a key: one of the 11 action keys `. h j k l n b u y > s`.
#[pyfunction]
pub fn action_from_key(key: &str) -> PyResult<usize> {
    let mut chars = key.chars();
    match (chars.next(), chars.next()) {
        (Some(c), None) => Action::from_key(c)
            .map(Action::index)
            .ok_or_else(|| invalid_key(c)),
        _ => Err(PyValueError::new_err(format!(
            "an action key is one character, got {key:?}"
        ))),
    }
}
