"""The worker side: what runs inside a pool's worker processes (``python -m
rogue_gym.worker``), never imported by the caller's side.

* ``__main__``: the entry point, which runs the pool's Rust worker loop.
* :mod:`~rogue_gym.worker.env_adapter`: builds each hosted gymnasium env from its
  cloudpickled callable and answers the loop's resets, steps and calls.
* :mod:`~rogue_gym.worker.vector_adapter`: the same for one vector env per worker.
"""
