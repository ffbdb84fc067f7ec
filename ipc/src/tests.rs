//! Tests of the transport: naming, round trips, waiting, cleanup.

use std::fs;
use std::path::Path as StdPath;
use std::time::{Duration, Instant};

use crate::cleanup::is_pool_name;
use crate::*;

/// A private runtime directory for one test (created 0700 if missing).
fn private_base(name: &str) -> std::path::PathBuf {
    let base = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
    crate::private::ensure_private_dir(&base).unwrap();
    base
}

#[test]
fn names_are_short_random_and_unique() {
    let base = StdPath::new("/tmp/x");
    let a = PoolId::new_unique(base).unwrap();
    let b = PoolId::new_unique(base).unwrap();
    assert_ne!(a.name(), b.name());
    assert!(is_pool_name(a.name()));
    assert_eq!(a.prefix().len(), 15);
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
    let base = private_base("rgp-ipc-test");
    let id = PoolId::new_unique(&base).unwrap();
    id.create_dirs().unwrap();
    let s = ChannelSettings { num_workers: 1 };
    {
        let sup_node = id.node("sup").unwrap();
        let sup = SupervisorPorts::new(&sup_node, 0, 4).unwrap();
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
            ready_ns: 0,
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
    let base = private_base("rgp-ipc-idle-test");
    let id = PoolId::new_unique(&base).unwrap();
    id.create_dirs().unwrap();
    let s = ChannelSettings { num_workers: 1 };
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
    let base = private_base("rgp-ipc-sweep-test");
    let live = PoolId::new_unique(&base).unwrap();
    live.create_dirs().unwrap();
    let dead = PoolId::new_unique(&base).unwrap();
    dead.create_dirs().unwrap();
    // Fake a dead owner.
    fs::write(dead.aux_dir().join("owner"), "4294967294 1\n").unwrap();
    // A pool being created: its owner file exists but is not written yet.
    let starting = PoolId::new_unique(&base).unwrap();
    starting.create_dirs().unwrap();
    fs::write(starting.aux_dir().join("owner"), "").unwrap();
    let removed = sweep_stale_pools(&base);
    assert!(removed.contains(&dead.name().to_string()));
    assert!(!dead.aux_dir().exists());
    assert!(live.aux_dir().exists());
    assert!(
        starting.aux_dir().exists(),
        "a young pool with an empty owner file is left alone"
    );
    remove_pool_files(&live).unwrap();
    remove_pool_files(&starting).unwrap();
    let _ = fs::remove_dir(&base);
}

/// Every mode bit a pool's path has beyond its owner's.
fn loose_paths(id: &PoolId) -> Vec<String> {
    use std::os::unix::fs::MetadataExt;
    let mut out = Vec::new();
    let mut todo: Vec<std::path::PathBuf> = pool_shm_files(id);
    todo.extend([id.root(), id.aux_dir()]);
    while let Some(p) = todo.pop() {
        let m = fs::symlink_metadata(&p).unwrap();
        if m.mode() & 0o077 != 0 || m.uid() != nix::unistd::geteuid().as_raw() {
            out.push(format!("{} {:o}", p.display(), m.mode()));
        }
        if m.is_dir() {
            todo.extend(fs::read_dir(&p).unwrap().map(|e| e.unwrap().path()));
        }
    }
    out
}

#[test]
fn every_path_of_a_live_pool_is_private() {
    let base = private_base("rgp-ipc-private-test");
    let id = PoolId::new_unique(&base).unwrap();
    id.create_dirs().unwrap();
    let s = ChannelSettings { num_workers: 1 };
    {
        let _buf = SharedBuffer::create("batch", 4096).unwrap();
        create_node_counter(&id).unwrap();
        let node = id.node("sup").unwrap();
        let _sup = SupervisorPorts::new(&node, 0, 4).unwrap();
        let _bl = BlockListener::new(&node, &s).unwrap();
        let w_node = id.node("w0").unwrap();
        let _w = WorkerPorts::new(&w_node, 0, 8, &s).unwrap();
        verify_pool_files(&id).unwrap();
        assert!(pool_shm_files(&id).len() >= 4, "{:?}", pool_shm_files(&id));
        assert_eq!(loose_paths(&id), Vec::<String>::new());
        // The node counter iceoryx2 would make 0666 is ours, 0600.
        let counter = pool_shm_files(&id)
            .into_iter()
            .find(|p| p.to_string_lossy().ends_with(".global_mgmt"))
            .expect("node counter");
        use std::os::unix::fs::MetadataExt;
        assert_eq!(fs::metadata(counter).unwrap().mode() & 0o777, 0o600);
    }
    remove_pool_files(&id).unwrap();
    assert!(pool_shm_files(&id).is_empty());
    let _ = fs::remove_dir(&base);
}

#[test]
fn a_planted_name_fails_cleanly_and_nothing_is_written_through_it() {
    let base = private_base("rgp-ipc-planted-test");
    let id = PoolId::new_unique(&base).unwrap();
    id.create_dirs().unwrap();
    // A link where the node counter goes, pointing at a file of ours: refused, file untouched.
    let victim = base.join("victim");
    fs::write(&victim, b"precious").unwrap();
    let counter = crate::pool_files::node_counter_path(&id).unwrap();
    std::os::unix::fs::symlink(&victim, &counter).unwrap();
    let err = create_node_counter(&id).unwrap_err();
    assert!(err.to_string().contains("File exists"), "{err}");
    assert_eq!(fs::read(&victim).unwrap(), b"precious");
    fs::remove_file(&counter).unwrap();
    // A loose (0644) file under the pool's prefix makes the pool's check fail.
    {
        use std::os::unix::fs::PermissionsExt;
        create_node_counter(&id).unwrap();
        fs::set_permissions(&counter, fs::Permissions::from_mode(0o644)).unwrap();
        let err = verify_pool_files(&id).unwrap_err();
        assert!(err.to_string().contains("open to group or others"), "{err}");
    }
    // An existing pool directory is never reused.
    assert!(id.create_dirs().is_err());
    remove_pool_files(&id).unwrap();
    let _ = fs::remove_file(&victim);
    let _ = fs::remove_dir(&base);
}

#[test]
fn runtime_dirs_that_are_not_private_are_refused() {
    use crate::private::ensure_private_dir;
    use std::os::unix::fs::PermissionsExt;
    let base = private_base("rgp-ipc-runtime-test");
    // A file, a link and a 0755 directory in the runtime directory's place.
    let file = base.join("file");
    fs::write(&file, b"").unwrap();
    let err = ensure_private_dir(&file).unwrap_err();
    assert!(err.to_string().contains("is not a directory"), "{err}");
    let link = base.join("link");
    std::os::unix::fs::symlink(&base, &link).unwrap();
    let err = ensure_private_dir(&link).unwrap_err();
    assert!(err.to_string().contains("symbolic link"), "{err}");
    let open = base.join("open");
    fs::create_dir(&open).unwrap();
    fs::set_permissions(&open, fs::Permissions::from_mode(0o755)).unwrap();
    let err = ensure_private_dir(&open).unwrap_err();
    assert!(err.to_string().contains("mode 0755"), "{err}");
    assert!(err.to_string().contains("ROGUE_GYM_RUNTIME_DIR"), "{err}");
    // A relative path, and a missing parent.
    assert!(ensure_private_dir(StdPath::new("relative")).is_err());
    assert!(ensure_private_dir(&base.join("no/such")).is_err());
    // A fresh one is made 0700; the sweep leaves a non-private pool directory alone.
    let fresh = base.join("fresh");
    ensure_private_dir(&fresh).unwrap();
    assert_eq!(
        fs::metadata(&fresh).unwrap().permissions().mode() & 0o777,
        0o700
    );
    let foreign = fresh.join("rg0123456789ab.d");
    fs::create_dir(&foreign).unwrap();
    fs::set_permissions(&foreign, fs::Permissions::from_mode(0o755)).unwrap();
    assert!(sweep_stale_pools(&fresh).is_empty());
    assert!(foreign.exists());
    fs::remove_dir_all(&base).unwrap();
}
