"""Small tools every AES node uses: throttled warnings and publish counters."""

from __future__ import annotations

import math
import time
from typing import Any

import rclpy

#: Seconds between repeated warnings of one kind.
WARN_PERIOD = 5.0
#: Logger of the message counts at shutdown (a logger of no node: no /rosout publisher).
COUNT_LOGGER = "published"


class ThrottledWarnings:
    """Warnings at most every ``period`` s per kind, the text before the first colon.

    rclpy's own ``throttle_duration_sec`` throttles per call site, so one kind of
    bad input would silence every other kind logged from the same line.

    >>> warn = ThrottledWarnings(node.get_logger())
    >>> warn("dropped /swarm/poses: a non-finite value")  # logged
    >>> warn("dropped /swarm/poses: 3 poses")  # same kind within 5 s: not logged
    """

    def __init__(self, logger: Any, period: float = WARN_PERIOD) -> None:
        self._logger = logger
        self._period = period
        self._last: dict[str, float] = {}

    def __call__(self, text: str) -> bool:
        """Log ``text`` unless its kind was logged less than ``period`` s ago; True if logged."""
        kind = text.partition(":")[0]
        now = time.monotonic()
        if now - self._last.get(kind, -math.inf) < self._period:
            return False
        self._last[kind] = now
        self._logger.warning(text)
        return True


class PublishCounter:
    """Messages published per topic, logged at shutdown.

    Counted at the publisher, so that a recording can be checked for losses
    (tests/system/test_recording.py reads the line :meth:`log` writes).
    """

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}
        self._topics: dict[int, str] = {}  # publisher id -> topic (a C call to look up)

    def publish(self, publisher: Any, msg: Any) -> None:
        """Publish ``msg`` and count it under the publisher's topic."""
        publisher.publish(msg)
        topic = self._topics.get(id(publisher))
        if topic is None:
            topic = self._topics[id(publisher)] = publisher.topic_name
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def add(self, topic: str, n: int = 1) -> None:
        self.counts[topic] = self.counts.get(topic, 0) + n

    def line(self, node_name: str) -> str:
        """``<node>: <topic> <n>, <topic> <n>, …`` (topics sorted)."""
        items = ", ".join(f"{topic} {n}" for topic, n in sorted(self.counts.items()))
        return f"{node_name}: {items}"

    def log(self, node_name: str) -> None:
        """Log the counts under the ``published`` logger: not the node's own logger,
        whose context (and /rosout) may already be gone at shutdown."""
        rclpy.logging.get_logger(COUNT_LOGGER).info(self.line(node_name))
