"""AES supervisor: swarm command (desired velocity, rotation centre, enable) and metrics."""
