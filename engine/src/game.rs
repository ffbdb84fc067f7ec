//! The game: one episode at a time, stepped by [`Action`]s, observed through [`ObsSpec`]s.

use serde::{Deserialize, Serialize};

use crate::action::{Action, Command};
use crate::actors::{Enemy, Player};
use crate::config::{ConfigError, EnemyKind, GameConfig, InitItem, Seeding};
use crate::dungeon::original::{self, OriginalStreams};
use crate::dungeon::{Floor, Generator, Surface, flag};
use crate::obs::{self, ObsBufMut, ObsError, ObsSource, ObsSpec, Status};
use crate::rng::{GameRng, Stream};
use crate::symbol::SYMBOL_OF_TILE;

/// Episode settings: the step limit and the reward for reaching a new deepest floor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EpisodeConfig {
    /// Steps after which the episode is truncated (default 1000; the paper used 500).
    pub max_steps: u32,
    /// Reward for each new deepest floor (default 50.0, as in the paper).
    pub stair_reward: f32,
}

impl Default for EpisodeConfig {
    fn default() -> Self {
        EpisodeConfig {
            max_steps: 1000,
            stair_reward: 50.0,
        }
    }
}

/// The result of one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepResult {
    /// Gold gained this step plus `stair_reward` for a new deepest floor.
    pub reward: f32,
    /// The episode ended: the player died or picked up the amulet.
    pub terminated: bool,
    /// The step limit was reached (and the episode did not terminate).
    pub truncated: bool,
}

/// A summary of the current episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EpisodeInfo {
    /// The seed of this episode.
    pub seed: u64,
    /// Steps taken.
    pub steps: u32,
    /// Current floor (1-based).
    pub floor: u32,
    /// Deepest floor reached.
    pub max_floor: u32,
    /// Gold carried.
    pub gold: u32,
    /// Current HP.
    pub hp: i32,
    /// Max HP.
    pub max_hp: i32,
    /// The player died (monster or starvation).
    pub died: bool,
    /// The player picked up the amulet.
    pub won: bool,
}

/// One game. Create it once, then `reset(seed)` for each episode; buffers are reused.
#[derive(Debug, Clone)]
pub struct Game {
    pub(crate) cfg: GameConfig,
    pub(crate) episode: EpisodeConfig,
    pub(crate) symbols: usize,
    /// Monster kinds sorted by rarity (the selection order).
    pub(crate) kinds: Vec<EnemyKind>,
    pub(crate) generator: Generator,
    pub(crate) floor: Floor,
    pub(crate) player: Player,
    pub(crate) enemies: Vec<Enemy>,
    /// Per cell: index + 1 of the monster standing there, 0 for none.
    pub(crate) enemy_at: Vec<u16>,
    /// The play stream (search, combat, monster moves, healing).
    pub(crate) rng: GameRng,
    /// The original's dungeon and item streams under `"seeding": "original"`.
    pub(crate) original: Option<OriginalStreams>,
    pub(crate) seed: u64,
    pub(crate) level: u32,
    pub(crate) max_floor: u32,
    pub(crate) steps: u32,
    pub(crate) terminated: bool,
    pub(crate) truncated: bool,
    pub(crate) died: bool,
    pub(crate) won: bool,
    pub(crate) reward: f32,
    /// Symbol index per cell (the observation screen).
    pub(crate) sym: Vec<u8>,
    /// ASCII tile per cell.
    pub(crate) ascii: Vec<u8>,
    /// Cells whose tile may have changed since the last refresh.
    pub(crate) dirty: Vec<u32>,
    /// Last message (for terminal play).
    pub(crate) message: String,
    /// BFS scratch for monster chase.
    pub(crate) dist: Vec<u16>,
    pub(crate) queue: Vec<u32>,
}

impl Game {
    /// Validates `config` and builds a game, reset with [`Game::default_seed`].
    pub fn new(config: &GameConfig, episode: EpisodeConfig) -> Result<Game, ConfigError> {
        config.validate()?;
        let mut kinds: Vec<EnemyKind> = config
            .enemies
            .enemies
            .iter()
            .filter_map(|p| p.resolve())
            .collect();
        kinds.sort_by_key(|k| k.rarity);
        let n = (config.width * config.height) as usize;
        let mut game = Game {
            cfg: config.clone(),
            episode,
            symbols: config.symbol_count(),
            kinds,
            generator: Generator::new(config),
            floor: Floor::default(),
            player: Player::default(),
            enemies: Vec::new(),
            enemy_at: vec![0; n],
            rng: GameRng::new(0, Stream::Play, 0),
            original: None,
            seed: 0,
            level: 0,
            max_floor: 0,
            steps: 0,
            terminated: false,
            truncated: false,
            died: false,
            won: false,
            reward: 0.0,
            sym: vec![0; n],
            ascii: vec![b' '; n],
            dirty: Vec::with_capacity(n),
            message: String::new(),
            dist: vec![u16::MAX; n],
            queue: Vec::with_capacity(n),
        };
        let seed = game.default_seed();
        game.reset(seed);
        Ok(game)
    }

    /// The seed `Game::new` starts with: the config's `seed` if set, else the low end of
    /// `seed_range`, else 0. (Use [`GameConfig::seed_for_episode`] for per-episode seeds.)
    pub fn default_seed(&self) -> u64 {
        self.cfg
            .seed
            .or(self.cfg.seed_range.map(|r| r[0]))
            .unwrap_or(0)
    }

    /// Starts a new episode on floor 1 of `seed`. Reuses all buffers.
    pub fn reset(&mut self, seed: u64) {
        self.seed = seed;
        self.rng = GameRng::new(seed, Stream::Play, 0);
        self.level = 0;
        self.max_floor = 0;
        self.steps = 0;
        self.terminated = false;
        self.truncated = false;
        self.died = false;
        self.won = false;
        self.reward = 0.0;
        self.message.clear();
        self.player = self.initial_player();
        self.original = (self.cfg.seeding == Seeding::Original).then(|| OriginalStreams::new(seed));
        self.new_level();
        if let Some(streams) = &mut self.original {
            streams.draw_starting_kit(&self.cfg);
        }
        self.max_floor = 1;
    }

    fn initial_player(&self) -> Player {
        let p = &self.cfg.player;
        let mut player = Player {
            hp: p.init_hp,
            max_hp: p.init_hp,
            str_cur: p.init_str,
            str_max: p.init_str,
            level: 1,
            food: p.hunger_time,
            weapon: (1, 4),
            ..Player::default()
        };
        let (mut armor, mut weapon) = (false, false);
        for item in &p.init_items {
            match item {
                InitItem::Noinit(n) if n.kind.name().eq_ignore_ascii_case("gold") => {
                    player.gold = player.gold.saturating_add(n.how_many)
                }
                InitItem::Armor(a) if !armor => {
                    armor = true;
                    // Validation guarantees the name is in the configured table.
                    let base = self.cfg.item.armor.defense_of(&a.name).unwrap_or(0);
                    player.defense = base + a.def_plus;
                }
                InitItem::Weapon(w) if !weapon => {
                    weapon = true;
                    player.weapon = self.cfg.item.weapon.dice_of(&w.name).unwrap_or((1, 4));
                    player.hit_plus = w.hit_plus;
                    player.dam_plus = w.dam_plus;
                }
                _ => {}
            }
        }
        player
    }

    /// Builds the next floor, places monsters and the player, and redraws the screen.
    pub(crate) fn new_level(&mut self) {
        self.level += 1;
        self.enemies.clear();
        self.enemy_at.fill(0);
        let start = match &mut self.original {
            // The original picks the start with the layout; our monsters avoid it.
            Some(streams) => {
                let slots = self.generator.slots();
                let start =
                    original::generate(&mut self.floor, slots, &self.cfg, self.level, streams);
                self.place_enemies(Some(start));
                start
            }
            // Ours places the monsters first; the start avoids them.
            None => {
                let mut drng =
                    self.generator
                        .generate(&mut self.floor, &self.cfg, self.seed, self.level);
                self.place_enemies(None);
                let enemy_at = &self.enemy_at;
                self.generator
                    .random_room_cell_where(&self.floor, &mut drng, |c| enemy_at[c] == 0)
                    .or_else(|| {
                        (0..self.floor.surface.len())
                            .find(|&c| self.floor.surface[c].walkable() && enemy_at[c] == 0)
                    })
                    .unwrap_or(self.floor.stairs)
            }
        };
        self.player.pos = start;
        self.player_in(start, true);
        self.render_all();
    }

    /// Plays one action. After the episode ended, input is ignored and the result repeats
    /// the end flags with reward 0 (see [`Game::is_over`]).
    pub fn step(&mut self, action: Action) -> StepResult {
        if self.is_over() {
            return self.result(0.0);
        }
        self.reward = 0.0;
        self.message.clear();
        self.act(action);
        self.end_step()
    }

    /// Plays a terminal command. A run (the original's `MoveUntil`) is one step: it repeats
    /// its move until the move fails, attacks, picks something up, lands on anything but floor
    /// or passage (a door, the stairs) or the episode ends; every repetition but that last one
    /// passes a turn, so a run blocked at once costs no turn.
    pub fn step_command(&mut self, command: Command) -> StepResult {
        let dir = match command {
            Command::Act(a) => return self.step(a),
            Command::Run(a) => match a.dir() {
                Some(dir) => dir,
                None => return self.step(a),
            },
        };
        if self.is_over() {
            return self.result(0.0);
        }
        self.reward = 0.0;
        self.message.clear();
        for _ in 0..(self.cfg.width + self.cfg.height) {
            let (before, reward) = (self.player.pos, self.reward);
            self.player_move(dir);
            let here = self.floor.surface[self.player.pos];
            if self.player.pos == before
                || self.reward != reward
                || self.terminated
                || !matches!(here, Surface::Floor | Surface::Passage)
            {
                break;
            }
            self.after_turn();
            if self.terminated {
                break;
            }
        }
        self.end_step()
    }

    fn end_step(&mut self) -> StepResult {
        self.steps += 1;
        if !self.terminated && self.steps >= self.episode.max_steps {
            self.truncated = true;
        }
        self.refresh_screen();
        self.result(self.reward)
    }

    fn result(&self, reward: f32) -> StepResult {
        StepResult {
            reward,
            terminated: self.terminated,
            truncated: self.truncated,
        }
    }

    /// Performs the action and, unless the episode ended, the turn (hunger, healing, monsters).
    fn act(&mut self, action: Action) {
        match action {
            Action::NoOp => {}
            Action::Search => self.search(),
            Action::DownStair => {
                if self.player.pos == self.floor.stairs
                    && self.floor.surface[self.player.pos] == Surface::Stair
                {
                    self.descend();
                } else {
                    self.set_message("Hmm... there seems to be no downstair");
                }
            }
            _ => {
                if let Some(dir) = action.dir() {
                    self.player_move(dir);
                }
            }
        }
        if !self.terminated {
            self.after_turn();
        }
    }

    fn descend(&mut self) {
        self.new_level();
        if self.level > self.max_floor {
            self.max_floor = self.level;
            self.reward += self.episode.stair_reward;
        }
    }

    /// Has the episode ended (terminated or truncated)?
    pub fn is_over(&self) -> bool {
        self.terminated || self.truncated
    }

    /// The episode summary.
    pub fn info(&self) -> EpisodeInfo {
        EpisodeInfo {
            seed: self.seed,
            steps: self.steps,
            floor: self.level,
            max_floor: self.max_floor,
            gold: self.player.gold,
            hp: self.player.hp,
            max_hp: self.player.max_hp,
            died: self.died,
            won: self.won,
        }
    }

    /// The player's status.
    pub fn status(&self) -> Status {
        let p = &self.player;
        Status {
            dungeon_level: self.level,
            gold: p.gold,
            hp_current: p.hp,
            hp_max: p.max_hp,
            str_current: p.str_cur,
            str_max: p.str_max,
            defense: p.defense,
            player_level: p.level,
            exp: p.exp,
            hunger: self.hunger_level(),
        }
    }

    /// The status line in the original's format, e.g.
    /// `Level:  1 Gold:     0 Hp: 12(12) Str: 16(16) Arm:  4 Exp:  1/ 0 `.
    pub fn status_line(&self) -> String {
        let s = self.status();
        let hunger = match s.hunger {
            0 => "",
            1 => "hungry",
            _ => "weak",
        };
        format!(
            "Level: {:2} Gold: {:5} Hp: {:2}({:2}) Str: {:2}({:2}) Arm: {:2} Exp: {:2}/{:2} {}",
            s.dungeon_level,
            s.gold,
            s.hp_current,
            s.hp_max,
            s.str_current,
            s.str_max,
            s.defense,
            s.player_level,
            s.exp,
            hunger
        )
    }

    /// The last message (row 0 in terminal play); empty if none this step.
    pub fn message(&self) -> &str {
        &self.message
    }

    pub(crate) fn set_message(&mut self, msg: &str) {
        self.message.clear();
        self.message.push_str(msg);
    }

    /// Screen height (rows, including the message and status rows).
    pub fn height(&self) -> usize {
        self.cfg.height as usize
    }

    /// Screen width.
    pub fn width(&self) -> usize {
        self.cfg.width as usize
    }

    /// The rendered screen as ASCII rows. Rows 0 and height-1 are blank; see
    /// [`Game::message`] and [`Game::status_line`] for what the terminal shows there.
    pub fn screen_rows(&self) -> impl Iterator<Item = &[u8]> + '_ {
        self.ascii.chunks_exact(self.width())
    }

    /// The screen as text (rows joined by newlines), for printing and tests.
    pub fn screen_string(&self) -> String {
        self.screen_rows()
            .map(|r| String::from_utf8_lossy(r).into_owned())
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// The symbol index of every cell, row-major (what `symbol_index` encodes).
    pub fn symbol_screen(&self) -> &[u8] {
        &self.sym
    }

    /// Number of symbols (one-hot channels without status and history).
    pub fn symbol_count(&self) -> usize {
        self.symbols
    }

    /// The config this game was built from.
    pub fn config(&self) -> &GameConfig {
        &self.cfg
    }

    /// The episode settings.
    pub fn episode_config(&self) -> EpisodeConfig {
        self.episode
    }

    /// The player's `(x, y)`.
    pub fn player_position(&self) -> (i32, i32) {
        self.floor.xy(self.player.pos)
    }

    /// The shape of the observation for `spec` (see [`crate::obs`] for layouts).
    pub fn observation_shape(&self, spec: &ObsSpec) -> Vec<usize> {
        obs::shape(spec, self.height(), self.width(), self.symbols)
    }

    /// The number of elements of the observation for `spec` (the product of its shape).
    pub fn observation_len(&self, spec: &ObsSpec) -> usize {
        self.observation_shape(spec).iter().product()
    }

    /// Writes the observation into `out` (length = product of the shape, dtype = spec's).
    pub fn write_obs(&self, spec: &ObsSpec, out: ObsBufMut<'_>) -> Result<(), ObsError> {
        let src = ObsSource {
            height: self.height(),
            width: self.width(),
            symbols: self.symbols,
            sym: &self.sym,
            ascii: &self.ascii,
            visited: &self.floor.visited,
            status: self.status(),
            amulet_level: self.cfg.dungeon.amulet_level,
        };
        obs::write(spec, &src, out)
    }

    // ----- screen maintenance -----

    /// Marks a cell for redraw.
    #[inline]
    pub(crate) fn touch(&mut self, i: usize) {
        self.dirty.push(i as u32);
    }

    /// Redraws the dirty cells (and every monster's cell, whose visibility depends on where
    /// the player is).
    pub(crate) fn refresh_screen(&mut self) {
        for k in 0..self.enemies.len() {
            let p = self.enemies[k].pos;
            self.dirty.push(p as u32);
        }
        for k in 0..self.dirty.len() {
            let i = self.dirty[k] as usize;
            let t = self.render_cell(i);
            self.ascii[i] = t;
            self.sym[i] = SYMBOL_OF_TILE[t as usize];
        }
        self.dirty.clear();
    }

    fn render_all(&mut self) {
        self.dirty.clear();
        let w = self.width();
        let n = self.ascii.len();
        for i in w..n - w {
            let t = self.render_cell(i);
            self.ascii[i] = t;
            self.sym[i] = SYMBOL_OF_TILE[t as usize];
        }
    }

    /// The tile shown at cell `i`.
    fn render_cell(&self, i: usize) -> u8 {
        if i == self.player.pos {
            return b'@';
        }
        let f = self.floor.flags[i];
        if f & (flag::VISIBLE | flag::DRAWN) != 0 {
            if self.floor.gold[i] > 0 {
                return b'*';
            }
            if self.floor.amulet == Some(i) {
                return b',';
            }
            let e = self.enemy_at[i];
            if e != 0 && self.enemy_seen(i) {
                let kind = self.enemies[e as usize - 1].kind;
                return self.kinds[kind as usize].tile;
            }
        }
        if f & flag::VISIBLE != 0 {
            self.floor.surface[i].tile()
        } else {
            b' '
        }
    }

    /// Is the monster on cell `i` drawn: adjacent to the player or in the same room zone?
    fn enemy_seen(&self, i: usize) -> bool {
        let (x, y) = self.floor.xy(i);
        let (px, py) = self.floor.xy(self.player.pos);
        let (dx, dy) = (x - px, y - py);
        dx * dx + dy * dy <= 2
            || (self.floor.zone[i] == self.floor.zone[self.player.pos]
                && self.floor.zone[i] != u16::MAX)
    }
}
