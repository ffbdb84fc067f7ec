//! `rogue-gym dump`: the floors of a range of seeds as generated, one JSON line per seed and
//! floor, in the record format of the original's dungeon oracle (see
//! `rogue_gym_engine::FloorRecord`).

use std::io::{BufWriter, Write};
use std::ops::Range;
use std::path::PathBuf;

use rogue_gym_engine::{GameConfig, floor_records};

/// Arguments of `dump`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Game config (JSON). Default: the paper's config.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Seeds: `A..B` (half-open) or one seed `A`.
    #[arg(long, value_parser = parse_seeds)]
    seed: Range<u64>,
    /// Floors per seed: 1 is the first; later floors are reached from the stairs.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    floors: u32,
    /// Write here instead of standard output.
    #[arg(long)]
    out: Option<PathBuf>,
}

fn parse_seeds(s: &str) -> Result<Range<u64>, String> {
    let num = |t: &str| {
        t.trim()
            .parse::<u64>()
            .map_err(|e| format!("{t:?} is not a seed (a u64): {e}"))
    };
    match s.split_once("..") {
        Some((a, b)) => {
            let (a, b) = (num(a)?, num(b)?);
            if a >= b {
                return Err(format!(
                    "the seed range {s} is empty: write A..B with A < B"
                ));
            }
            Ok(a..b)
        }
        None => {
            let a = num(s)?;
            Ok(a..a.saturating_add(1))
        }
    }
}

/// Write the records; errors are messages for the user.
pub(crate) fn run(args: Args) -> Result<(), String> {
    let config = crate::load_config(args.config.as_deref(), GameConfig::paper())?;
    let sink: Box<dyn Write> = match &args.out {
        Some(p) => Box::new(
            std::fs::File::create(p).map_err(|e| format!("cannot create {}: {e}", p.display()))?,
        ),
        None => Box::new(std::io::stdout().lock()),
    };
    let mut out = BufWriter::new(sink);
    for seed in args.seed {
        let records = floor_records(&config, seed, args.floors).map_err(|e| e.to_string())?;
        for r in records {
            let line = serde_json::to_string(&r).map_err(|e| e.to_string())?;
            writeln!(out, "{line}").map_err(|e| format!("cannot write: {e}"))?;
        }
    }
    out.flush().map_err(|e| format!("cannot write: {e}"))
}
