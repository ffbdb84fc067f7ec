//! Tests of the transport: naming, round trips, waiting, cleanup.

use std::fs;
use std::path::Path as StdPath;
use std::time::{Duration, Instant};

use crate::cleanup::is_pool_name;
use crate::*;

#[test]
fn names_are_short_and_unique() {
    let a = PoolId::new_unique(StdPath::new(DEFAULT_BASE_DIR)).unwrap();
    let b = PoolId::new_unique(StdPath::new(DEFAULT_BASE_DIR)).unwrap();
    assert_ne!(a.name(), b.name());
    assert!(is_pool_name(a.name()));
    assert_eq!(a.prefix().len(), 11);
    assert!(PoolId::from_parts("x", &StdPath::new("/tmp").join("a".repeat(90))).is_err());
    assert!(PoolId::from_parts("bad/name", StdPath::new("/tmp")).is_err());
}

#[test]
fn own_process_is_alive_and_start_time_readable() {
    assert!(process_start_time(std::process::id()).is_some());
    assert!(process_start_time(u32::MAX - 1).is_none());
}

#[test]
fn pubsub_round_trip_and_cleanup() {
    let base = std::env::temp_dir().join("rgp-ipc-test");
    let id = PoolId::new_unique(&base).unwrap();
    id.create_dirs().unwrap();
    let s = ChannelSettings {
        num_workers: 1,
        max_borrowed: 2,
    };
    {
        let sup_node = id.node("sup").unwrap();
        let sup = SupervisorPorts::new(&sup_node, 0, 4, &s).unwrap();
        let bl = BlockListener::new(&sup_node, &s).unwrap();
        let w_node = id.node("w0").unwrap();
        let w = WorkerPorts::new(&w_node, 0, 8, &s).unwrap();
        sup.send_cmd(1, 7, 3, |p| p.copy_from_slice(&[1, 2, 3]))
            .unwrap();
        let mut got = None;
        hybrid_wait::<IpcError>(
            w.cmd_listener(),
            &WaitPolicy::default(),
            Some(Instant::now() + Duration::from_secs(5)),
            |_| {
                got = w.try_recv_cmd()?;
                Ok(got.is_some())
            },
        )
        .unwrap();
        let c = got.unwrap();
        assert_eq!(c.user_header().kind, 7);
        assert_eq!(&c.payload()[..3], &[1, 2, 3]);
        let mut b = w.loan_block(8).unwrap();
        b.payload_mut().fill(9);
        *b.user_header_mut() = BlockHeader {
            seq: 1,
            generation: 0,
            worker: 0,
            kind: 2,
        };
        w.send_block(b).unwrap();
        let mut blk = None;
        let out = hybrid_wait::<IpcError>(
            bl.listener(),
            &WaitPolicy::default(),
            Some(Instant::now() + Duration::from_secs(5)),
            |_| {
                blk = sup.try_recv()?;
                Ok(blk.is_some())
            },
        )
        .unwrap();
        assert_eq!(out, WaitOutcome::Done);
        let blk = blk.unwrap();
        assert_eq!(blk.payload(), &[9u64; 8]);
        assert_eq!(words_as_bytes(blk.payload()).len(), 64);
    }
    assert!(!pool_shm_files(&id).is_empty());
    remove_pool_files(&id).unwrap();
    assert!(pool_shm_files(&id).is_empty());
    assert!(!id.root().exists() && !id.aux_dir().exists());
    let _ = fs::remove_dir(&base);
}

/// CPU time (utime + stime, clock ticks) of the calling thread.
fn thread_cpu_ticks() -> u64 {
    let s = fs::read_to_string("/proc/thread-self/stat").unwrap();
    let rest = &s[s.rfind(')').unwrap() + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    f[11].parse::<u64>().unwrap() + f[12].parse::<u64>().unwrap()
}

#[test]
fn idle_wait_blocks_instead_of_spinning() {
    let base = std::env::temp_dir().join("rgp-ipc-idle-test");
    let id = PoolId::new_unique(&base).unwrap();
    id.create_dirs().unwrap();
    let s = ChannelSettings {
        num_workers: 1,
        max_borrowed: 2,
    };
    {
        let node = id.node("sup").unwrap();
        let bl = BlockListener::new(&node, &s).unwrap();
        let before = thread_cpu_ticks();
        let t0 = Instant::now();
        let mut idles = 0;
        let out = hybrid_wait::<IpcError>(
            bl.listener(),
            &WaitPolicy::default(),
            Some(Instant::now() + Duration::from_millis(400)),
            |c| {
                if c == WaitCall::Idle {
                    idles += 1;
                }
                Ok(false)
            },
        )
        .unwrap();
        assert_eq!(out, WaitOutcome::TimedOut);
        assert!(t0.elapsed() >= Duration::from_millis(400));
        assert!(idles >= 10, "idle hook runs every block slice ({idles})");
        // 400 ms of waiting cost (much) less than 100 ms of CPU (ticks are 10 ms).
        assert!(thread_cpu_ticks() - before < 10);
    }
    remove_pool_files(&id).unwrap();
    let _ = fs::remove_dir(&base);
}

#[test]
fn sweep_removes_pools_of_dead_owners_only() {
    let base = std::env::temp_dir().join("rgp-ipc-sweep-test");
    let live = PoolId::new_unique(&base).unwrap();
    live.create_dirs().unwrap();
    let dead = PoolId::new_unique(&base).unwrap();
    dead.create_dirs().unwrap();
    // Fake a dead owner.
    fs::write(dead.aux_dir().join("owner"), "4294967294 1\n").unwrap();
    let removed = sweep_stale_pools(&base);
    assert!(removed.contains(&dead.name().to_string()));
    assert!(!dead.aux_dir().exists());
    assert!(live.aux_dir().exists());
    remove_pool_files(&live).unwrap();
    let _ = fs::remove_dir(&base);
}
