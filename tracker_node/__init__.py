"""aes-tracker: robot poses from an overhead camera's ArUco markers (SPEC §8)."""
