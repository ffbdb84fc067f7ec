"""Entry point of a pool worker process: ``python -m rogue_gym.worker ARGS...``.

The pool's supervisor spawns this module; it runs the pool's Rust worker loop (with the GIL
released) and exits with its status. Not meant to be run by hand.
"""

import sys

from rogue_gym import _native

if __name__ == "__main__":
    sys.exit(_native.worker_main(sys.argv[1:]))
