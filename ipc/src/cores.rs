//! The cores this process really has: the CPUs its affinity mask allows, and its cgroup's CPU
//! quota (cgroup v2 `cpu.max`, v1 `cpu.cfs_quota_us` / `cpu.cfs_period_us`, the lowest along
//! the cgroup's ancestors), rounded up. Every default of a pool that counts cores and every
//! waiting decision reads them here; Python through `rogue_gym._native.usable_cores()`.
//!
//! A pod limited to 4 CPUs of a 64-core node sees 64 CPUs in `os.cpu_count()`, and 64 workers
//! that each believe they have a core to poll on spin against each other.

use std::path::{Path, PathBuf};

/// What bounds the cores of a process.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cores {
    /// CPUs the affinity mask allows.
    pub affinity: usize,
    /// The cgroup's CPU quota in CPUs (`quota / period`), when it has one.
    pub quota: Option<f64>,
}

impl Cores {
    /// The cores usable at once: the affinity count, at most the quota rounded up; 1 or more.
    pub fn usable(&self) -> usize {
        let quota = self
            .quota
            .map_or(usize::MAX, |q| q.ceil().max(1.0) as usize);
        self.affinity.min(quota).max(1)
    }
}

/// This process's cores (see the module docs).
pub fn cores() -> Cores {
    Cores {
        affinity: affinity_count().unwrap_or(1),
        quota: cgroup_quota(Path::new("/")),
    }
}

/// [`Cores::usable`] of this process.
pub fn usable_cores() -> usize {
    cores().usable()
}

/// CPUs the affinity mask of this process allows.
fn affinity_count() -> Option<usize> {
    use nix::sched::{CpuSet, sched_getaffinity};
    let set = sched_getaffinity(nix::unistd::Pid::from_raw(0)).ok()?;
    Some(
        (0..CpuSet::count())
            .filter(|&c| set.is_set(c).unwrap_or(false))
            .count(),
    )
}

/// The CPU quota of this process's cgroup, in CPUs, reading every file below `root` (`/`, or
/// a fake tree in tests): `proc/self/cgroup` for the cgroup, `proc/self/mountinfo` for where
/// its hierarchy is mounted, and the quota files of the cgroup and of each ancestor, the lowest
/// of them. `None` when there is no quota or nothing can be read.
pub fn cgroup_quota(root: &Path) -> Option<f64> {
    let cgroups = std::fs::read_to_string(root.join("proc/self/cgroup")).ok()?;
    let mounts = std::fs::read_to_string(root.join("proc/self/mountinfo")).ok()?;
    let mut lowest: Option<f64> = None;
    for line in cgroups.lines() {
        // `id:controllers:path`; v2 is `0::path`.
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let v2 = controllers.is_empty();
        if !v2 && !controllers.split(',').any(|c| c == "cpu") {
            continue;
        }
        let Some(dir) = mount_of(&mounts, v2, path) else {
            continue;
        };
        // The cgroup and its ancestors up to the mount's root: the lowest quota binds.
        let mut d = Some(root.join(dir.strip_prefix("/").unwrap_or(&dir)));
        let top = root.join(
            mount_point(&mounts, v2)
                .unwrap_or_default()
                .strip_prefix("/")
                .unwrap_or(Path::new("")),
        );
        while let Some(here) = d {
            let q = if v2 { quota_v2(&here) } else { quota_v1(&here) };
            if let Some(q) = q {
                lowest = Some(lowest.map_or(q, |l| l.min(q)));
            }
            d = (here != top)
                .then(|| here.parent().map(Path::to_path_buf))
                .flatten();
        }
    }
    lowest
}

/// `cpu.max`: `quota period`, or `max period` for none.
fn quota_v2(dir: &Path) -> Option<f64> {
    let text = std::fs::read_to_string(dir.join("cpu.max")).ok()?;
    let mut it = text.split_whitespace();
    let quota: f64 = it.next()?.parse().ok()?;
    let period: f64 = it.next()?.parse().ok()?;
    (quota > 0.0 && period > 0.0).then_some(quota / period)
}

/// `cpu.cfs_quota_us` (-1: none) over `cpu.cfs_period_us`.
fn quota_v1(dir: &Path) -> Option<f64> {
    let read = |f: &str| -> Option<f64> {
        std::fs::read_to_string(dir.join(f))
            .ok()?
            .trim()
            .parse()
            .ok()
    };
    let (quota, period) = (read("cpu.cfs_quota_us")?, read("cpu.cfs_period_us")?);
    (quota > 0.0 && period > 0.0).then_some(quota / period)
}

/// A cgroup hierarchy's mount: `(mount point, root of the mount within the hierarchy)` of the
/// v2 hierarchy, or of the v1 hierarchy with the `cpu` controller.
fn mount_entry(mountinfo: &str, v2: bool) -> Option<(PathBuf, String)> {
    for line in mountinfo.lines() {
        // `id parent major:minor root mount-point options ... - fstype source super-options`
        let Some((left, right)) = line.split_once(" - ") else {
            continue;
        };
        let fields: Vec<&str> = left.split(' ').collect();
        let right: Vec<&str> = right.split(' ').collect();
        let (Some(&root), Some(&point), Some(&fstype)) =
            (fields.get(3), fields.get(4), right.first())
        else {
            continue;
        };
        let cpu = || {
            right
                .get(2)
                .is_some_and(|o| o.split(',').any(|opt| opt == "cpu"))
        };
        if (v2 && fstype == "cgroup2") || (!v2 && fstype == "cgroup" && cpu()) {
            return Some((PathBuf::from(point), root.to_string()));
        }
    }
    None
}

fn mount_point(mountinfo: &str, v2: bool) -> Option<PathBuf> {
    mount_entry(mountinfo, v2).map(|(p, _)| p)
}

/// Where cgroup `path` (as `/proc/self/cgroup` says) is in the file system.
fn mount_of(mountinfo: &str, v2: bool, path: &str) -> Option<PathBuf> {
    let (point, root) = mount_entry(mountinfo, v2)?;
    // A container's mount shows its own cgroup as the root: strip that prefix.
    let rel = path.strip_prefix(root.as_str()).unwrap_or(path);
    Some(point.join(rel.trim_start_matches('/')))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fake root with the given files.
    fn tree(name: &str, files: &[(&str, &str)]) -> PathBuf {
        let root = std::env::temp_dir().join(format!("rg-cores-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (path, text) in files {
            let p = root.join(path);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
        }
        root
    }

    const V2_MOUNT: &str = "30 25 0:26 / /sys/fs/cgroup rw,nosuid - cgroup2 cgroup2 rw\n";
    const V1_MOUNT: &str = "\
31 25 0:27 / /sys/fs/cgroup/memory rw - cgroup cgroup rw,memory
32 25 0:28 / /sys/fs/cgroup/cpu,cpuacct rw - cgroup cgroup rw,cpu,cpuacct
";

    #[test]
    fn a_v2_quota_is_read_and_rounded_up_with_its_ancestors() {
        let root = tree(
            "v2",
            &[
                ("proc/self/cgroup", "0::/kubepods/pod1/c1\n"),
                ("proc/self/mountinfo", V2_MOUNT),
                ("sys/fs/cgroup/kubepods/pod1/c1/cpu.max", "max 100000\n"),
                ("sys/fs/cgroup/kubepods/pod1/cpu.max", "250000 100000\n"),
                ("sys/fs/cgroup/kubepods/cpu.max", "800000 100000\n"),
            ],
        );
        assert_eq!(cgroup_quota(&root), Some(2.5));
        let cores = Cores {
            affinity: 64,
            quota: cgroup_quota(&root),
        };
        assert_eq!(cores.usable(), 3);
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn a_v1_quota_is_read_from_the_cpu_hierarchy() {
        let root = tree(
            "v1",
            &[
                (
                    "proc/self/cgroup",
                    "5:memory:/job\n4:cpu,cpuacct:/job\n0::/\n",
                ),
                ("proc/self/mountinfo", V1_MOUNT),
                ("sys/fs/cgroup/cpu,cpuacct/job/cpu.cfs_quota_us", "100000\n"),
                (
                    "sys/fs/cgroup/cpu,cpuacct/job/cpu.cfs_period_us",
                    "100000\n",
                ),
                ("sys/fs/cgroup/cpu,cpuacct/cpu.cfs_quota_us", "-1\n"),
                ("sys/fs/cgroup/cpu,cpuacct/cpu.cfs_period_us", "100000\n"),
            ],
        );
        assert_eq!(cgroup_quota(&root), Some(1.0));
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn a_container_that_sees_its_cgroup_as_the_root_reads_its_own_quota() {
        let root = tree(
            "ns",
            &[
                ("proc/self/cgroup", "0::/\n"),
                (
                    "proc/self/mountinfo",
                    "30 25 0:26 /kubepods/pod1 /sys/fs/cgroup ro - cgroup2 cgroup2 rw\n",
                ),
                ("sys/fs/cgroup/cpu.max", "50000 100000\n"),
            ],
        );
        assert_eq!(cgroup_quota(&root), Some(0.5));
        let cores = Cores {
            affinity: 8,
            quota: Some(0.5),
        };
        assert_eq!(cores.usable(), 1, "at least one core, rounded up");
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn no_quota_or_nothing_readable_is_none_and_the_affinity_counts() {
        let root = tree(
            "none",
            &[
                ("proc/self/cgroup", "0::/user.slice\n"),
                ("proc/self/mountinfo", V2_MOUNT),
                ("sys/fs/cgroup/user.slice/cpu.max", "max 100000\n"),
            ],
        );
        assert_eq!(cgroup_quota(&root), None);
        assert_eq!(cgroup_quota(&root.join("missing")), None);
        let cores = Cores {
            affinity: 3,
            quota: None,
        };
        assert_eq!(cores.usable(), 3);
        assert!(usable_cores() >= 1);
        std::fs::remove_dir_all(root).unwrap();
    }
}
