"""``python -m rogue_gym.doctor``: a machine that fits passes; each problem fails its check with
the fix (a small /dev/shm, too few open files, too many workers for the CPUs)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys

from rogue_gym import doctor

from test_shm import _in_small_shm


def test_this_machine_passes_for_a_small_native_pool() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "rogue_gym.doctor", "--num-envs", "8", "--seconds", "0.3"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    for name in ("cpus", "/dev/shm", "open files", "runtime directory", "a pool"):
        assert f"[ok  ] {name}" in done.stdout, done.stdout
    assert "this pool needs" in done.stdout and "steps/s" in done.stdout


def test_a_pool_that_does_not_fit_a_small_shm_fails_with_the_fix() -> None:
    """Only the workers' channels live in /dev/shm: 32 workers need about 2 MiB of it, more
    than what a 64 MiB /dev/shm has left once something else filled it to 1 MiB."""
    done = _in_small_shm(
        """
        import sys
        from rogue_gym import doctor
        with open("/dev/shm/filler", "wb") as f:
            f.write(bytes(63 << 20))
        sys.exit(doctor.main(["RogueGym-v0", "--num-envs", "64", "--num-workers", "32", "--seconds", "0.2"]))
        """
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert "[FAIL] /dev/shm" in done.stdout and "--shm-size" in done.stdout
    assert "[FAIL] a pool: did not start: no room in /dev/shm" in done.stdout


def test_too_few_open_files_and_too_many_workers_say_how_to_fix_them() -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (300, hard))
    try:
        files = doctor.check_open_files(num_workers=8)
    finally:
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    assert not files.ok and "ulimit -n" in files.fix
    cpus = len(os.sched_getaffinity(0))
    many = doctor.check_cpus(num_workers=4 * cpus + 1)
    assert not many.ok and "num_workers <=" in many.fix
    assert doctor.check_cpus(num_workers=1).ok
