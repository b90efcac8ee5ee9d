"""Tuning the gains: the optimiser, its cost and the paper's study (SPEC §3, §6).

One job per module:

* :mod:`~aes_ros.optim.tcacs` — the TCACS minimiser (SPEC §6);
* :mod:`~aes_ros.optim.benchmarks` — standard test functions TCACS is validated on;
* :mod:`~aes_ros.optim.cost` — the Monte-Carlo tuning cost J (E10).
"""
