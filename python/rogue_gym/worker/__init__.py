"""The worker side: what runs inside a pool's worker processes (``python -m
rogue_gym.worker``). The caller's side imports one module of it, :mod:`agent_rows`, whose
PettingZoo rows it also runs in-process (``rogue_gym.multi_agent.AgentRows``); the rest it
never imports (``tests/python/test_layering.py``).

* ``__main__``: the entry point, which runs the pool's Rust worker loop.
* :mod:`~rogue_gym.worker.env_adapter`: builds each hosted gymnasium env from its
  cloudpickled callable and answers the loop's resets, steps and calls.
* :mod:`~rogue_gym.worker.vector_adapter`: the same for one vector env per worker.
* :mod:`~rogue_gym.worker.agent_rows`: a PettingZoo env as one vector env of its agents' rows.
"""
