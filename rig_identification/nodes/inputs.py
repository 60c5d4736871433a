"""A consumer node's input streams: validated, gaps recorded, decoded in batches.

Inputs at 1 kHz: the consumer nodes subscribe with ``raw=True`` (the callback only queues the
serialized bytes) and decode each topic's queue in one ``np.frombuffer`` every few ms
(:class:`~.codec.MessageLayout`, :class:`RawInput`); they publish their outputs serialized the
same way.  A Python message object per sample cost ~35 µs in rclpy, a raw take ~10 µs (6 topics
at 1 kHz, measured).  Validation (:class:`InputGuard`) and the stamp-order merge
(:class:`~.merge.StampMerger`) work on the batches.

Faults: :class:`InputGuard` records stamp gaps per input topic, :class:`~.diagnostics.Diagnostics`
reports each input OK / WARN stale / ERROR stopped on /diagnostics.  A node process that is
killed leaves its readers matched to the reliable KEEP_ALL writers until its DDS participant
lease expires; :func:`~.environment.dds_profile` shortens that lease to 3 s (``config/dds/fastdds.xml``)
so that the writers are not held back for Fast DDS's default 20 s.
"""
from __future__ import annotations

import math
import time

import numpy as np
from rclpy.node import Node

from ..io.quality import SHORT_GAP
from .codec import MessageLayout, PersistentReason
from .frames import Endpoint


class InputGuard:
    """Validate incoming messages; count and report the rejected ones; watch each input
    stream for gaps and silence.

    A message is rejected when its frame id is not the expected one, a value is not
    finite, or its stamp is not after the previous accepted stamp of the same topic.
    Rejections are logged as warnings throttled per topic (every ``period`` s at most,
    with the number suppressed since), and counted for the diagnostics.  A reason that
    will hold for every later message (:class:`~.codec.PersistentReason`: a frame id that
    is not the expected one) is warned once per topic and reason, naming the parameter to
    set; the messages are still counted.  Warnings name a remapped topic by its resolved
    name (:meth:`alias`); the keys stay the node's own names (``/rig/imu``).

    Gaps: two consecutive accepted stamps of a topic further apart than
    ``max(max_gap, 1.5 × the topic's typical sampling period)`` (the offline rule of
    :func:`~rig_identification.io.quality.find_bad_spans`) are recorded in ``gaps[topic]``
    as (t0, t1) header stamps (the last ``keep_gaps``).  ``last_arrival[topic]`` is the
    monotonic wall time of the latest message (silence: see :class:`Diagnostics`).
    """

    def __init__(self, node: Node, period: float = 5.0, max_gap: float | None = None, keep_gaps: int = 100):
        self.node = node
        self.period = period
        self.max_gap = SHORT_GAP if max_gap is None else max_gap
        self.keep_gaps = keep_gaps
        self.last: dict[str, float] = {}
        self.received: dict[str, int] = {}
        self.rejected: dict[str, int] = {}
        self.gaps: dict[str, list[tuple[float, float]]] = {}
        self.last_arrival: dict[str, float] = {}
        self._dt: dict[str, list[float]] = {}  # first intervals of each topic (typical period)
        self._period: dict[str, float] = {}
        self._warned: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}
        self._said_once: set[tuple[str, str]] = set()
        self.resolved: dict[str, str] = {}

    def alias(self, topic: str, resolved: str) -> None:
        """Name ``topic`` (the node's own name) as ``resolved`` (after remapping) in warnings."""
        if resolved != topic:
            self.resolved[topic] = resolved

    def label(self, topic: str) -> str:
        """``topic``, or ``/my/imu (remapped /rig/imu)`` when it is remapped."""
        r = self.resolved.get(topic)
        return topic if r is None else f"{r} (remapped {topic})"

    def expect(self, topic: str) -> None:
        """Declare an input topic (reported on /diagnostics before its first message)."""
        self.received.setdefault(topic, 0)
        self.rejected.setdefault(topic, 0)

    def accept_batch(self, topic: str, t: np.ndarray, values: np.ndarray, bad: dict | None = None) -> np.ndarray:
        """Validate a batch: stamps t (n,) s, values (n, k), ``bad`` {row: reason}
        for rows refused before (decoding).  Returns the (n,) mask of accepted rows."""
        n = len(t)
        self.received[topic] = self.received.get(topic, 0) + n
        if n == 0:
            return np.ones(0, bool)
        self.last_arrival[topic] = time.monotonic()
        finite = np.isfinite(values).all(1) & np.isfinite(t)
        prev = self.last.get(topic, -math.inf)
        if not bad and finite.all() and t[0] > prev and (n == 1 or (t[1:] > t[:-1]).all()):
            self._watch_gaps(topic, t if prev == -math.inf else np.concatenate([[prev], t]))
            self.last[topic] = float(t[-1])
            return finite
        good = finite.copy()
        for i in (bad or {}):
            good[i] = False
        before = np.maximum.accumulate(np.concatenate([[prev], np.where(good, t, -math.inf)]))[:-1]
        ok = good & (t > before)
        if not ok.all():
            for i in np.nonzero(~ok)[0].tolist():
                if bad and i in bad:
                    why = bad[i]
                elif not finite[i]:
                    why = f"non-finite value at stamp {t[i]:.6f}"
                else:
                    why = f"stamp {t[i]:.6f} s not after the previous one ({before[i]:.6f} s)"
                self.reject(topic, why)
        if ok.any():
            ta = t[ok]
            self._watch_gaps(topic, ta if prev == -math.inf else np.concatenate([[prev], ta]))
            self.last[topic] = float(ta[-1])
        return ok

    def _watch_gaps(self, topic: str, ts: np.ndarray) -> None:
        """Record the gaps between consecutive accepted stamps ``ts`` of ``topic``."""
        if len(ts) < 2:
            return
        dt = ts[1:] - ts[:-1]
        period = self._period.get(topic)
        if period is None:  # typical period: median of the first 50 intervals
            first = self._dt.setdefault(topic, [])
            first.extend(dt[:50 - len(first)].tolist())
            if len(first) >= 50:
                self._period[topic] = period = float(np.median(first))
                del self._dt[topic]
            else:
                period = float(np.median(first))
        limit = max(self.max_gap, 1.5 * period)
        if dt.max() <= limit:
            return
        big = np.nonzero(dt > limit)[0]
        if len(big):
            spans = self.gaps.setdefault(topic, [])
            spans.extend((float(ts[i]), float(ts[i + 1])) for i in big.tolist())
            del spans[:-self.keep_gaps]

    def gaps_in(self, lo: float, hi: float, topics=None) -> list[tuple[str, float, float]]:
        """Gaps (topic, t0, t1) overlapping the stamp window [lo, hi], including an open one
        when a topic's last stamp is older than ``hi`` by more than its gap threshold."""
        out = []
        for topic in (self.gaps if topics is None else topics):
            for a, b in self.gaps.get(topic, []):
                if a < hi and b > lo:
                    out.append((topic, a, b))
        for topic in (self.last if topics is None else topics):
            last = self.last.get(topic)
            if last is None:
                continue
            limit = max(self.max_gap, 1.5 * self._period.get(topic, 0.0))
            if hi - last > limit and last < hi:
                out.append((topic, last, hi))
        return sorted(out, key=lambda g: g[1])

    def reject(self, topic: str, why: str) -> None:
        """Count a rejected message of ``topic`` and warn: throttled per topic, or once per
        topic and reason for a :class:`~.codec.PersistentReason`."""
        self.rejected[topic] = self.rejected.get(topic, 0) + 1
        if isinstance(why, PersistentReason):
            if (topic, why) not in self._said_once:
                self._said_once.add((topic, why))
                self.node.get_logger().warn(
                    f"dropped a malformed message on {self.label(topic)}: {why}; every further message like it "
                    "is dropped without a warning (counted on /diagnostics as rejected)")
            return None
        now = time.monotonic()
        if now - self._warned.get(topic, -math.inf) >= self.period:
            extra = self._suppressed.pop(topic, 0)
            more = f" ({extra} more rejected since the last warning)" if extra else ""
            self.node.get_logger().warn(f"dropped a malformed message on {self.label(topic)}: {why}{more}")
            self._warned[topic] = now
        else:
            self._suppressed[topic] = self._suppressed.get(topic, 0) + 1
        return None

    def core_error(self, topic: str, err: Exception) -> None:
        """The core refused an input that passed the checks: count it like a malformed message."""
        self.reject(topic, f"{type(err).__name__}: {err}")


class RawInput:
    """A stream subscription that takes serialized messages (``raw=True``: the callback only
    queues the bytes) and decodes and validates them in batches (:meth:`take`)."""

    def __init__(self, node: Node, guard: "InputGuard", topic: str, layout: MessageLayout, qos):
        self.topic, self.layout, self.guard = topic, layout, guard
        self.pending: list[bytes] = []
        self.sub = node.create_subscription(layout.msg_type, topic, self.pending.append, qos, raw=True)
        guard.expect(topic)
        guard.alias(topic, self.sub.topic_name)

    def endpoint(self) -> Endpoint:
        """This input for :func:`~.frames.log_interface` (resolved name, type, expected frames)."""
        names = {"header.frame_id": "frame", "child_frame_id": "child"}
        note = ", ".join(f"{names.get(path, path)} {value}" for path, value in self.layout.strings.items())
        return Endpoint(self.sub, note)

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """Decode, validate (:meth:`InputGuard.accept_batch`) and return the accepted
        messages queued so far: stamps (m,) s and values (m, k)."""
        raws = self.pending[:]
        if not raws:
            return np.empty(0), np.empty((0, len(self.layout.fields)))
        del self.pending[:len(raws)]
        t, vals, bad = self.layout.decode(raws)
        ok = self.guard.accept_batch(self.topic, t, vals, bad)
        if ok.all():
            return t, vals
        return t[ok], vals[ok]
