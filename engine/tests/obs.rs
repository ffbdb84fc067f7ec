//! Observation shapes, layouts and buffer errors.

use rogue_gym_engine::*;

fn game() -> Game {
    let mut g = Game::new(&GameConfig::paper(), EpisodeConfig::default()).unwrap();
    g.reset(3);
    g
}

#[test]
fn paper_shape_and_onehot() {
    let g = game();
    let spec = ObsSpec::paper();
    assert_eq!(g.observation_shape(&spec), vec![17, 16, 32]);
    let mut buf = vec![7u8; 17 * 16 * 32];
    g.write_obs(&spec, ObsBufMut::U8(&mut buf)).unwrap();
    let hw = 16 * 32;
    for i in 0..hw {
        let hot: Vec<usize> = (0..17).filter(|&c| buf[c * hw + i] == 1).collect();
        assert_eq!(hot.len(), 1);
        assert_eq!(hot[0], g.symbol_screen()[i] as usize);
    }
    // Rows 0 and h-1 are blank.
    for x in 0..32 {
        assert_eq!(buf[x], 1);
        assert_eq!(buf[15 * 32 + x], 1);
    }
    assert_eq!(
        (0..hw).filter(|&i| buf[hw + i] == 1).count(),
        1,
        "one player"
    );
}

#[test]
fn all_layouts() {
    let g = game();
    let full = StatusFlags::FULL;
    let flags3 = StatusFlags::DUNGEON_LEVEL | StatusFlags::HP_CURRENT | StatusFlags::EXP;
    let cases: Vec<(ObsSpec, Vec<usize>)> = vec![
        (
            ObsSpec {
                status: flags3,
                history: true,
                dtype: Dtype::F32,
                ..ObsSpec::paper()
            },
            vec![21, 16, 32],
        ),
        (
            ObsSpec {
                status: full,
                ..ObsSpec::paper()
            },
            vec![26, 16, 32],
        ),
        (
            ObsSpec {
                encoding: Encoding::SymbolIndex,
                ..ObsSpec::paper()
            },
            vec![16, 32],
        ),
        (
            ObsSpec {
                encoding: Encoding::SymbolIndex,
                history: true,
                ..ObsSpec::paper()
            },
            vec![2, 16, 32],
        ),
        (
            ObsSpec {
                encoding: Encoding::Gray,
                dtype: Dtype::F32,
                ..ObsSpec::paper()
            },
            vec![1, 16, 32],
        ),
        (
            ObsSpec {
                encoding: Encoding::Gray,
                history: true,
                ..ObsSpec::paper()
            },
            vec![2, 16, 32],
        ),
        (
            ObsSpec {
                encoding: Encoding::Ascii,
                ..ObsSpec::paper()
            },
            vec![16, 32],
        ),
        (
            ObsSpec {
                encoding: Encoding::StatusVector,
                ..ObsSpec::paper()
            },
            vec![9],
        ),
        (
            ObsSpec {
                encoding: Encoding::StatusVector,
                status: flags3,
                dtype: Dtype::F32,
                ..ObsSpec::paper()
            },
            vec![3],
        ),
    ];
    for (spec, shape) in cases {
        assert_eq!(g.observation_shape(&spec), shape, "{spec:?}");
        let n = shape.iter().product();
        match spec.dtype {
            Dtype::U8 => g.write_obs(&spec, ObsBufMut::U8(&mut vec![0; n])).unwrap(),
            Dtype::F32 => g
                .write_obs(&spec, ObsBufMut::F32(&mut vec![0.0; n]))
                .unwrap(),
        }
    }
}

#[test]
fn status_planes_hold_raw_or_normalised_values() {
    let g = game();
    let hw = 16 * 32;
    let flags = StatusFlags::DUNGEON_LEVEL | StatusFlags::HP_CURRENT | StatusFlags::EXP;
    let spec = ObsSpec {
        status: flags,
        history: true,
        dtype: Dtype::F32,
        ..ObsSpec::paper()
    };
    let mut buf = vec![0f32; 21 * hw];
    g.write_obs(&spec, ObsBufMut::F32(&mut buf)).unwrap();
    assert!(buf[17 * hw..18 * hw].iter().all(|&v| v == 1.0));
    assert!(buf[18 * hw..19 * hw].iter().all(|&v| v == 12.0));
    assert!(buf[19 * hw..20 * hw].iter().all(|&v| v == 0.0));
    assert_eq!(
        buf[20 * hw..].iter().filter(|&&v| v == 1.0).count(),
        1,
        "history: start cell"
    );
    let spec = ObsSpec {
        normalize_status: true,
        ..spec
    };
    g.write_obs(&spec, ObsBufMut::F32(&mut buf)).unwrap();
    assert!(
        buf[18 * hw..19 * hw].iter().all(|&v| v == 1.0),
        "hp / max hp"
    );
    let mut v = vec![0f32; 9];
    g.write_obs(
        &ObsSpec {
            encoding: Encoding::StatusVector,
            dtype: Dtype::F32,
            ..ObsSpec::paper()
        },
        ObsBufMut::F32(&mut v),
    )
    .unwrap();
    assert_eq!(v, vec![1.0, 12.0, 12.0, 16.0, 16.0, 4.0, 1.0, 0.0, 0.0]);
}

#[test]
fn gray_and_ascii_match_the_screen() {
    let g = game();
    let mut gray = vec![0f32; 16 * 32];
    g.write_obs(
        &ObsSpec {
            encoding: Encoding::Gray,
            dtype: Dtype::F32,
            ..ObsSpec::paper()
        },
        ObsBufMut::F32(&mut gray),
    )
    .unwrap();
    for (v, &s) in gray.iter().zip(g.symbol_screen()) {
        assert_eq!(*v, f32::from(s) / 17.0);
    }
    let mut ascii = vec![0u8; 16 * 32];
    g.write_obs(
        &ObsSpec {
            encoding: Encoding::Ascii,
            ..ObsSpec::paper()
        },
        ObsBufMut::U8(&mut ascii),
    )
    .unwrap();
    assert_eq!(
        ascii,
        g.screen_rows().flatten().copied().collect::<Vec<u8>>()
    );
    assert!(ascii.contains(&b'@'));
}

#[test]
fn wrong_buffers_are_errors() {
    let g = game();
    let spec = ObsSpec::paper();
    let e = g
        .write_obs(&spec, ObsBufMut::U8(&mut [0u8; 10]))
        .unwrap_err();
    assert!(
        e.to_string().contains("expected 8704") && e.to_string().contains("10"),
        "{e}"
    );
    let e = g
        .write_obs(&spec, ObsBufMut::F32(&mut vec![0f32; 8704]))
        .unwrap_err();
    assert!(matches!(
        e,
        ObsError::WrongDtype {
            expected: Dtype::U8,
            got: Dtype::F32
        }
    ));
}

#[test]
fn names_parse() {
    for (s, e) in [
        ("symbol_onehot", Encoding::SymbolOnehot),
        ("symbol_index", Encoding::SymbolIndex),
        ("gray", Encoding::Gray),
        ("ascii", Encoding::Ascii),
        ("status", Encoding::StatusVector),
    ] {
        assert_eq!(s.parse::<Encoding>().unwrap(), e);
        assert_eq!(e.to_string(), s);
    }
    assert_eq!("u8".parse::<Dtype>().unwrap(), Dtype::U8);
    assert_eq!("f32".parse::<Dtype>().unwrap(), Dtype::F32);
    assert!("f64".parse::<Dtype>().is_err());
    assert!("rgb".parse::<Encoding>().is_err());
}

#[test]
fn actions() {
    assert_eq!(NUM_ACTIONS, 11);
    let keys: String = Action::ALL.iter().map(|a| a.key()).collect();
    assert_eq!(keys, ".hjklnbuy>s");
    for (i, a) in Action::ALL.iter().enumerate() {
        assert_eq!(Action::from_index(i), Some(*a));
        assert_eq!(*a as usize, i);
        assert_eq!(Action::from_key(a.key()), Some(*a));
    }
    assert_eq!(Action::from_key('j'), Some(Action::Down));
    assert_eq!(Action::from_index(11), None);
    assert_eq!(Action::try_from(9u8), Ok(Action::DownStair));
    assert_eq!(Action::try_from(11u8), Err(11));
    assert_eq!(game().observation_len(&ObsSpec::paper()), 17 * 16 * 32);
    assert_eq!(Action::from_key('x'), None);
    assert_eq!(Command::from_key('L'), Some(Command::Run(Action::Right)));
    assert_eq!(Command::from_key('S'), None);
}

#[test]
fn status_line_format() {
    let g = game();
    assert_eq!(
        g.status_line(),
        "Level:  1 Gold:     0 Hp: 12(12) Str: 16(16) Arm:  4 Exp:  1/ 0 "
    );
}

#[test]
fn obs_spec_json_round_trips_and_errors_name_the_key() {
    use rogue_gym_engine::{Dtype, Encoding, StatusFlags};
    use serde_json::json;
    assert_eq!(
        ObsSpec::from_json(&serde_json::Value::Null).unwrap(),
        ObsSpec::paper()
    );
    let s = ObsSpec {
        encoding: Encoding::Gray,
        dtype: Dtype::F32,
        status: StatusFlags(5),
        normalize_status: true,
        history: true,
    };
    assert_eq!(ObsSpec::from_json(&s.to_json()).unwrap(), s);
    let aliases = ObsSpec::from_json(&json!({"encoding": "onehot", "dtype": "u8"})).unwrap();
    assert_eq!(aliases.encoding, Encoding::SymbolOnehot);
    for (bad, key) in [
        (json!({"encoding": "pixels"}), "pixels"),
        (json!({"dtype": 3}), "dtype"),
        (json!({"status": 4096}), "status"),
        (json!({"history": "yes"}), "history"),
        (json!({"colour": true}), "colour"),
        (json!([1, 2]), "object"),
    ] {
        let e = ObsSpec::from_json(&bad).unwrap_err().to_string();
        assert!(e.contains(key), "{bad}: {e}");
    }
}
