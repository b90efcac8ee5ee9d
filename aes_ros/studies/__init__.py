"""Studies built on sweeps (``aes-swarm explore``): :mod:`.pareto` (the front behind the
paper's gains), :mod:`.noise` (the noise phase diagram), :mod:`.robustness` (the gains
under noise, size and failures); :mod:`.common` holds what they share."""
