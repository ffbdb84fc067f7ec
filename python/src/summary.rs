//! `_native.floor_summary(config_json, seed)`: difficulty metadata of floor 1 of a seed, for
//! the evaluator's per-seed manifest (`rogue_gym.evaluate --manifest-only`).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rogue_gym_engine::GameConfig;

/// Difficulty metadata of floor 1 of `seed` under the game config `config_json`.
///
/// Returns a dict with `seed`, `level`, `rooms`, `normal_rooms`, `maze_rooms`, `dark_rooms`,
/// `gone_rooms`, `doors`, `hidden_doors`, `passage_cells`, `hidden_passages`, `gold_piles`,
/// `gold_total`, `stairs_distance` (moves from the start to the stairs without searching, or
/// `None` if the stairs need a search) and `stairs_distance_unhidden` (the same with every
/// hidden passage and secret door found). See `rogue_gym_engine::FloorSummary`.
/// Raises `ValueError` for an invalid config.
#[pyfunction]
#[pyo3(signature = (config_json, seed))]
pub fn floor_summary<'py>(
    py: Python<'py>,
    config_json: &str,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg =
        GameConfig::from_json(config_json).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let s = rogue_gym_engine::floor_summary(&cfg, seed)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("seed", s.seed)?;
    d.set_item("level", s.level)?;
    d.set_item("rooms", s.rooms)?;
    d.set_item("normal_rooms", s.normal_rooms)?;
    d.set_item("maze_rooms", s.maze_rooms)?;
    d.set_item("dark_rooms", s.dark_rooms)?;
    d.set_item("gone_rooms", s.gone_rooms)?;
    d.set_item("doors", s.doors)?;
    d.set_item("hidden_doors", s.hidden_doors)?;
    d.set_item("passage_cells", s.passage_cells)?;
    d.set_item("hidden_passages", s.hidden_passages)?;
    d.set_item("gold_piles", s.gold_piles)?;
    d.set_item("gold_total", s.gold_total)?;
    d.set_item("stairs_distance", s.stairs_distance)?;
    d.set_item("stairs_distance_unhidden", s.stairs_distance_unhidden)?;
    Ok(d)
}
