//! Rule tests on hand-made floors.

use crate::config::{Chase, CustomEnemy, Dice, EnemiesConfig, EnemyPreset};
use crate::dungeon::{Surface, flag};
use crate::*;

fn quiet() -> GameConfig {
    GameConfig {
        enemies: EnemiesConfig {
            enemies: vec![],
            ..Default::default()
        },
        ..GameConfig::paper()
    }
}

const ROOM: [&str; 5] = ["-------", "|.....|", "|..@..+", "|.....|", "-------"];

#[test]
fn lit_room_is_shown_on_entry() {
    let g = Game::from_layout(&quiet(), EpisodeConfig::default(), &ROOM, false);
    assert_eq!(g.tile_at(1, 2), b'.');
    assert_eq!(g.tile_at(6, 3), b'+');
    assert_eq!(g.tile_at(3, 3), b'@');
}

#[test]
fn dark_room_shows_only_3x3() {
    let rows = [
        "---------",
        "|.......|",
        "|...@...|",
        "|.......|",
        "|.......|",
        "---------",
    ];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, true);
    // Floor within one cell of (4,3) is visible; farther floor is not.
    assert_eq!(g.tile_at(3, 2), b'.');
    assert_eq!(g.tile_at(5, 4), b'.');
    assert_eq!(g.tile_at(1, 2), b' ');
    assert_eq!(g.tile_at(7, 5), b' ');
    g.step(Action::Right);
    g.step(Action::Right);
    // The player is at (6,3): the old neighbourhood is dark again.
    assert_eq!(g.tile_at(6, 3), b'@');
    assert_eq!(g.tile_at(3, 3), b' ');
    assert_eq!(g.tile_at(7, 4), b'.');
    let visible_floor = g.ascii.iter().filter(|&&t| t == b'.').count();
    assert!(
        visible_floor <= 8,
        "only the 3x3 around the player: {visible_floor}"
    );
}

#[test]
fn gold_pickup_gives_reward() {
    let rows = ["-------", "|.....|", "|..@*.|", "|.....|", "-------"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    let r = g.step(Action::Right);
    assert_eq!(r.reward, 10.0);
    assert_eq!(g.status().gold, 10);
    assert_eq!(g.step(Action::Left).reward, 0.0);
}

#[test]
fn search_finds_hidden_passage_and_secret_door() {
    let rows = ["-------", "|....@&~", "|.....|", "-------"];
    let mut g = Game::from_layout(
        &quiet(),
        EpisodeConfig {
            max_steps: 10_000,
            ..Default::default()
        },
        &rows,
        false,
    );
    let door = g.floor.idx(6, 2);
    assert_eq!(g.tile_at(6, 2), b'|');
    assert!(
        g.step(Action::Right).reward == 0.0 && g.player_position() == (5, 2),
        "secret door blocks"
    );
    let mut n = 0;
    while g.floor.flags[door] & flag::LOCKED != 0 {
        g.step(Action::Search);
        n += 1;
        assert!(n < 200);
    }
    assert_eq!(g.tile_at(6, 2), b'+');
    g.step(Action::Right);
    assert_eq!(g.player_position(), (6, 2));
    let hidden = g.floor.idx(7, 2);
    assert_eq!(
        g.tile_at(7, 2),
        b' ',
        "hidden passage is not revealed on approach"
    );
    let mut n = 0;
    while g.floor.flags[hidden] & flag::HIDDEN != 0 {
        g.step(Action::Search);
        n += 1;
        assert!(n < 200);
    }
    assert_eq!(g.floor.surface[hidden], Surface::Passage);
    assert_eq!(g.tile_at(7, 2), b'#');
}

#[test]
fn descending_gives_stair_reward_once_per_new_floor() {
    let rows = ["-------", "|.....|", "|..@%.|", "|.....|", "-------"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    assert_eq!(g.step(Action::DownStair).reward, 0.0, "not on the stairs");
    assert_eq!(g.status().dungeon_level, 1);
    g.step(Action::Right);
    let r = g.step(Action::DownStair);
    assert_eq!(r.reward, 50.0);
    assert_eq!(g.info().floor, 2);
    assert_eq!(g.info().max_floor, 2);
    // Walk to the new stairs with the generator's own map: teleport for the test.
    g.player.pos = g.floor.stairs;
    let r = g.step(Action::DownStair);
    assert_eq!(r.reward, 50.0);
    assert_eq!(g.info().max_floor, 3);
}

#[test]
fn amulet_pickup_wins() {
    let rows = ["-------", "|.....|", "|..@,.|", "|.....|", "-------"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    assert_eq!(g.tile_at(4, 3), b',');
    let r = g.step(Action::Right);
    assert!(r.terminated && !r.truncated);
    assert!(g.info().won && !g.info().died);
    // Stepping after the end is ignored.
    let again = g.step(Action::Left);
    assert_eq!(
        again,
        StepResult {
            reward: 0.0,
            terminated: true,
            truncated: false
        }
    );
    assert_eq!(g.player_position(), (4, 3));
}

#[test]
fn starvation_kills() {
    let mut cfg = quiet();
    cfg.player.hunger_time = 20;
    let mut g = Game::from_layout(&cfg, EpisodeConfig::default(), &ROOM, false);
    for _ in 0..19 {
        assert!(!g.step(Action::NoOp).terminated);
    }
    assert_eq!(g.status().hunger, 2);
    let r = g.step(Action::NoOp);
    assert!(r.terminated);
    assert!(g.info().died);
}

#[test]
fn noop_passes_a_turn() {
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &ROOM, false);
    let food = g.player.food;
    g.step(Action::NoOp);
    g.step(Action::NoOp);
    assert_eq!(g.player.food, food - 2);
    assert_eq!(g.info().steps, 2);
}

#[test]
fn max_steps_truncates() {
    let mut g = Game::from_layout(
        &quiet(),
        EpisodeConfig {
            max_steps: 3,
            stair_reward: 50.0,
        },
        &ROOM,
        false,
    );
    assert!(!g.step(Action::NoOp).truncated);
    assert!(!g.step(Action::NoOp).truncated);
    let r = g.step(Action::NoOp);
    assert!(r.truncated && !r.terminated);
    assert!(g.is_over());
    assert_eq!(g.step(Action::Left).reward, 0.0);
    assert_eq!(g.info().steps, 3);
}

#[test]
fn diagonal_moves_blocked_at_doors_and_corners() {
    let rows = ["-----", "|...|", "|..@+#", "|...|#", "-----#"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    g.step(Action::Right);
    assert_eq!(g.player_position(), (4, 3), "onto the door");
    g.step(Action::RightDown);
    assert_eq!(g.player_position(), (4, 3), "no diagonal step off a door");
    g.step(Action::Right);
    g.step(Action::Down);
    assert_eq!(g.player_position(), (5, 4));
}

fn tough_config() -> GameConfig {
    let mut cfg = quiet();
    cfg.enemies.enemies = vec![EnemyPreset::Custom(CustomEnemy {
        attack: vec![Dice { times: 1, max: 3 }],
        attr: 0,
        defense: 10,
        exp: 30,
        gold: 0,
        level: 20,
        name: "brute".into(),
        tile: b'Z',
        rarelity: 0,
    })];
    cfg
}

#[test]
fn player_kills_monster_in_several_hits() {
    let rows = ["-------", "|.....|", "|..@Z.|", "|.....|", "-------"];
    let mut g = Game::from_layout(&tough_config(), EpisodeConfig::default(), &rows, false);
    g.enemies[0].hp = 25; // mace 2d4+1 does at most 9
    g.player.max_hp = 10_000;
    g.player.hp = 10_000;
    let mut attacks = 0;
    while g.enemies[0].alive {
        g.step(Action::Right);
        attacks += 1;
        assert!(attacks < 500);
        if g.enemies[0].alive {
            assert!(g.enemies[0].hp > 0);
        }
    }
    assert!(attacks > 2, "25 HP needs at least 3 hits");
    assert_eq!(g.enemy_at[g.floor.idx(4, 3)], 0);
    assert_eq!(g.tile_at(4, 3), b'.');
    assert_eq!(g.status().exp, 30);
    assert!(g.status().player_level >= 3, "30 exp passes 10 and 20");
}

#[test]
fn attacking_a_sleeping_monster_has_no_bonus() {
    // The attack wakes the monster before its roll (as in the original), so a sleeping and an
    // awake monster are hit alike: with the same play stream, the same outcome every time.
    let rows = ["-------", "|.....|", "|..@Z.|", "|.....|", "-------"];
    let mut differ = 0;
    for seed in 0..300u64 {
        let hp_after = |awake: bool| {
            let mut g = Game::from_layout(&tough_config(), EpisodeConfig::default(), &rows, false);
            g.rng = crate::rng::GameRng::new(seed, crate::rng::Stream::Play, 0);
            g.enemies[0].hp = 1000;
            g.enemies[0].awake = awake;
            g.player_attack(0);
            assert!(g.enemies[0].awake, "the attack wakes the monster");
            g.enemies[0].hp
        };
        differ += usize::from(hp_after(false) != hp_after(true));
    }
    assert_eq!(
        differ, 0,
        "a sleeping monster was hit differently in {differ} of 300 plays"
    );
}

#[test]
fn monster_damages_player() {
    let rows = ["-------", "|.....|", "|..@Z.|", "|.....|", "-------"];
    let mut g = Game::from_layout(
        &tough_config(),
        EpisodeConfig {
            max_steps: 10_000,
            ..Default::default()
        },
        &rows,
        false,
    );
    let mut turns = 0;
    while g.status().hp_current == 12 {
        g.step(Action::NoOp);
        turns += 1;
        assert!(turns < 100);
    }
    assert!(g.status().hp_current < 12);
    while !g.is_over() {
        g.step(Action::NoOp);
    }
    assert!(g.info().died && g.status().hp_current == 0);
}

/// A lit room: the player at its west wall, a monster at its east wall.
const CHASE_ROOM: [&str; 5] = [
    "-----------",
    "|.........|",
    "|@.......Z|",
    "|.........|",
    "-----------",
];

#[test]
fn monster_chases_player() {
    let mut g = Game::from_layout(
        &tough_config(),
        EpisodeConfig::default(),
        &CHASE_ROOM,
        false,
    );
    g.step(Action::NoOp);
    assert_eq!(g.floor.xy(g.enemies[0].pos), (8, 3));
    for _ in 0..6 {
        g.step(Action::NoOp);
    }
    assert_eq!(g.floor.xy(g.enemies[0].pos), (2, 3));
}

#[test]
fn chase_switch_original_side_steps_around_a_blocker() {
    // A 1-high room: the front brute sleeps in the way, the rear one is awake.
    let rows = ["----------", "|@....ZZ.|", "----------"];
    let rear_after_a_turn = |chase: Chase| {
        let mut cfg = tough_config();
        cfg.enemies.chase = chase;
        let mut g = Game::from_layout(&cfg, EpisodeConfig::default(), &rows, false);
        g.enemies[0].awake = false;
        g.step(Action::NoOp);
        g.floor.xy(g.enemies[1].pos)
    };
    // Ours waits: no free cell is closer.
    assert_eq!(rear_after_a_turn(Chase::Closer), (7, 2));
    // The original steps to the free neighbour nearest the player, here away from it.
    assert_eq!(rear_after_a_turn(Chase::Original), (8, 2));
}

#[test]
fn chase_switch_original_still_chases_and_attacks() {
    let mut cfg = tough_config();
    cfg.enemies.chase = Chase::Original;
    let mut g = Game::from_layout(&cfg, EpisodeConfig::default(), &CHASE_ROOM, false);
    for _ in 0..7 {
        g.step(Action::NoOp);
    }
    assert_eq!(g.floor.xy(g.enemies[0].pos), (2, 3));
    let hp = g.player.hp;
    for _ in 0..20 {
        g.step(Action::NoOp);
    }
    assert!(g.player.hp < hp, "the brute next to the player attacks");
}

#[test]
fn spawn_on_objects_lets_monsters_start_on_gold_or_stairs() {
    let on_objects = |allowed: bool| {
        let mut cfg = GameConfig {
            enemies: EnemiesConfig {
                appear_rate_gold: 100,
                appear_rate_nogold: 100,
                spawn_on_objects: allowed,
                ..Default::default()
            },
            ..GameConfig::paper()
        };
        cfg.dungeon.room_num_x = 2;
        let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
        let mut count = 0;
        for seed in 0..300 {
            g.reset(seed);
            count += g
                .enemies
                .iter()
                .filter(|e| g.floor.gold[e.pos] > 0 || e.pos == g.floor.stairs)
                .count();
        }
        count
    };
    assert_eq!(on_objects(false), 0);
    assert!(on_objects(true) > 0);
}

#[test]
fn every_symbol_channel_is_live() {
    let rows = ["-------", "|.....|", "|..@Z,", "|.....|", "-------"];
    let g = Game::from_layout(
        &GameConfig {
            enemies: EnemiesConfig::default(),
            ..GameConfig::paper()
        },
        EpisodeConfig::default(),
        &rows,
        false,
    );
    assert_eq!(g.symbol_count(), 43);
    let spec = ObsSpec::paper();
    let shape = g.observation_shape(&spec);
    assert_eq!(shape, vec![43, 16, 32]);
    let mut buf = vec![0u8; shape.iter().product()];
    g.write_obs(&spec, ObsBufMut::U8(&mut buf)).unwrap();
    let hw = 16 * 32;
    let plane_sum = |c: usize| {
        buf[c * hw..(c + 1) * hw]
            .iter()
            .map(|&v| v as usize)
            .sum::<usize>()
    };
    assert_eq!(plane_sum(42), 1, "Z is the last channel");
    assert_eq!(plane_sum(16), 1, "the amulet channel");
    assert_eq!(plane_sum(1), 1, "one player");
    for i in 0..hw {
        assert_eq!((0..43).map(|c| buf[c * hw + i] as usize).sum::<usize>(), 1);
    }
}

#[test]
fn deep_floors_have_the_amulet_and_never_panic() {
    let mut cfg = GameConfig::default();
    cfg.dungeon.amulet_level = 5;
    let mut g = Game::new(
        &cfg,
        EpisodeConfig {
            max_steps: 100_000,
            stair_reward: 50.0,
        },
    )
    .unwrap();
    let mut state = 3u64;
    let mut deepest = 0;
    for seed in 0..40 {
        g.reset(seed);
        g.player.max_hp = 1_000_000;
        g.player.hp = 1_000_000;
        for _ in 1..40u32 {
            let floor = g.info().floor;
            deepest = deepest.max(floor);
            assert_eq!(
                g.floor.amulet.is_some(),
                floor >= 5,
                "amulet from amulet_level on"
            );
            for _ in 0..20 {
                state = splitmix64(state);
                g.step(Action::ALL[(state % 11) as usize]);
            }
            if g.is_over() {
                break;
            }
            // Teleport to the stairs (a monster may stand there: then skip the floor check).
            let stairs = g.floor.stairs;
            if g.enemy_at[stairs] != 0 {
                break;
            }
            g.player.pos = stairs;
            let r = g.step(Action::DownStair);
            assert!(r.reward >= 50.0 || r.terminated, "{r:?}");
            if g.is_over() {
                break;
            }
        }
    }
    assert!(deepest >= 30, "deepest floor {deepest}");
}

#[test]
fn corridors_are_revealed_orthogonally() {
    let rows = ["-----", "|...|", "|..@+##", "|...| ##", "-----  #"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    g.step(Action::Right); // onto the door (4,3)
    assert_eq!(g.tile_at(5, 3), b'#');
    assert_eq!(g.tile_at(6, 3), b' ', "two cells away");
    g.step(Action::Right); // (5,3)
    assert_eq!(g.tile_at(6, 3), b'#');
    assert_eq!(g.tile_at(6, 4), b' ', "diagonal corridor cell stays unseen");
    g.step(Action::Right); // (6,3)
    assert_eq!(g.tile_at(6, 4), b'#');
    // Seen corridor cells stay visible.
    assert_eq!(g.tile_at(5, 3), b'#');
}

#[test]
fn run_stops_at_a_door() {
    let rows = ["--------", "|......|", "|@.....+##", "|......|", "--------"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    let food = g.player.food;
    g.step_command(Command::Run(Action::Right));
    assert_eq!(g.player_position(), (7, 3), "the run stops on the door");
    // As the original's MoveUntil: one step, a turn for every move but the last.
    assert_eq!(g.info().steps, 1);
    assert_eq!(food - g.player.food, 5);
    // Blocked at once: no turn passes.
    let rows = ["-----", "|..@|", "-----"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    let food = g.player.food;
    g.step_command(Command::Run(Action::Right));
    assert_eq!((g.info().steps, g.player.food), (1, food));
}

#[test]
fn run_stops_after_picking_up_gold_without_a_turn() {
    let rows = ["--------", "|@.*...|", "--------"];
    let mut g = Game::from_layout(&quiet(), EpisodeConfig::default(), &rows, false);
    let food = g.player.food;
    let r = g.step_command(Command::Run(Action::Right));
    assert_eq!(g.player_position(), (3, 2));
    assert!(r.reward > 0.0);
    assert_eq!(
        food - g.player.food,
        1,
        "the move onto the gold passes no turn"
    );
}

#[test]
fn hide_dungeon_false_shows_the_floor() {
    let cfg = GameConfig {
        hide_dungeon: false,
        ..GameConfig::paper()
    };
    let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
    g.reset(4);
    let stairs = g.floor.xy(g.floor.stairs);
    assert_eq!(g.tile_at(stairs.0, stairs.1), b'%');
    let walls = g.ascii.iter().filter(|&&t| t == b'-' || t == b'|').count();
    assert!(walls > 20);
}
