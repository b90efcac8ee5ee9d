"""Parameter sweeps of the offline simulator (``aes-swarm sweep``): :mod:`.spec` (what
is swept), :mod:`.runs` (simulating points in batches), :mod:`.engine` (local or Dask,
resumable outputs), :mod:`.figures`."""
