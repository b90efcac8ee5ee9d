"""aes-tracker: robot poses from an overhead camera's ArUco markers (docs/design.md#tracking)."""
