"""The generalization evaluator's parts, one job per module; :mod:`rogue_gym.evaluate` is its
command line and :func:`rogue_gym.evaluate.evaluate` puts them together.

* :mod:`~rogue_gym.scoring.stats`: bootstrap confidence intervals across seeds, agent results;
* :mod:`~rogue_gym.scoring.policies`: the policy interface, the random agent, loading a policy;
* :mod:`~rogue_gym.scoring.episodes`: playing a suite's scheduled episodes (pool or in process);
* :mod:`~rogue_gym.scoring.reports`: the seed manifest and the files written.
"""
