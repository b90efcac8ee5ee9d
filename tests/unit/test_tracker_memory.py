"""The tracker's memory of the robots between frames: nothing invented, ages, lost."""

from __future__ import annotations

import numpy as np

from aes_ros.tracking.tracks import Tracks

S = 1_000_000_000


def test_a_robot_unseen_keeps_its_last_pose_and_ages() -> None:
    tracks = Tracks(3, references=frozenset({249}))
    tracks.update(0, np.array([0, 1, 2]), np.arange(6.0).reshape(3, 2), np.zeros(3))
    assert tracks.complete
    report = tracks.update(S // 2, np.array([0, 2]), np.ones((2, 2)), np.full(2, 0.5))
    assert list(report.seen) == [0, 2] and report.unknown == ()
    assert np.array_equal(tracks.positions[1], [2.0, 3.0]) and tracks.headings[1] == 0.0
    assert np.allclose(tracks.ages(S), [0.5, 1.0, 0.5])
    assert list(tracks.lost(S, lost_after=0.75)) == [1]


def test_nothing_is_published_for_a_robot_never_seen() -> None:
    tracks = Tracks(3)
    tracks.update(0, np.array([2, 0]), np.zeros((2, 2)), np.zeros(2))
    assert not tracks.complete and list(tracks.missing()) == [1]
    assert np.isnan(tracks.positions[1]).all() and tracks.ages(S)[1] == np.inf
    assert list(tracks.lost(S, lost_after=10.0)) == [1]


def test_unknown_ids_are_ignored_and_named_references_are_not_unknown() -> None:
    tracks = Tracks(2, references=frozenset({249, 248}))
    report = tracks.update(0, np.array([1, 7, 249, -1]), np.arange(8.0).reshape(4, 2), np.zeros(4))
    assert list(report.seen) == [1] and report.unknown == (7, -1)
    assert np.array_equal(tracks.positions[1], [0.0, 1.0]) and tracks.seen_ns[0] == -1


def test_an_older_frame_does_not_move_a_robot_back_in_time() -> None:
    tracks = Tracks(1)
    tracks.update(2 * S, np.array([0]), np.array([[1.0, 1.0]]), np.array([0.1]))
    report = tracks.update(S, np.array([0]), np.array([[0.0, 0.0]]), np.array([0.0]))
    assert len(report.seen) == 0
    assert np.array_equal(tracks.positions[0], [1.0, 1.0]) and tracks.seen_ns[0] == 2 * S
