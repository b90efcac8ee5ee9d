"""Tuning the gains: the optimiser, its cost and the paper's study (docs/design.md#tuning, #tcacs).

One job per module:

* :mod:`~aes_ros.optim.tcacs` — the TCACS minimiser (docs/design.md#tcacs);
* :mod:`~aes_ros.optim.frame` — its rotated sampling frame and spread weights (steps 5–6);
* :mod:`~aes_ros.optim.benchmarks` — standard test functions TCACS is validated on;
* :mod:`~aes_ros.optim.cost` — the Monte-Carlo tuning cost J (E10);
* :mod:`~aes_ros.optim.tuning` — one tuning run (``aes-swarm optimize``) and its outputs;
* :mod:`~aes_ros.optim.study` — the paper's tuning study (``aes-swarm study``);
* :mod:`~aes_ros.optim.figures` — the figures of both, from arrays to PNG.
"""
