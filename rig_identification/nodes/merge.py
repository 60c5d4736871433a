"""Merging stamped input streams into one feed in header-stamp order (:class:`StampMerger`).

Topics are delivered independently over DDS, so arrival order is not stamp order; the
tracker node feeds its core in stamp order, as the offline replay does.
"""
from __future__ import annotations

import heapq
import math


class StampMerger:
    """Merge several stamped streams into one feed in header-stamp order.

    Topics are delivered independently (and, under back-pressure or a DDS repair, with
    different delays), so arrival order is not stamp order.  ``push`` buffers an event
    and returns the events that are now safe to hand on, sorted by ``(stamp, rank)``: those
    with a stamp no later than every stream's next possible stamp, or older than the newest
    stamp minus ``max_delay`` (a silent or stalled stream delays the feed by at most that
    much).  A stream's next possible stamp is its latest stamp plus ``lookahead`` times its
    sampling period (its shortest stamp interval so far; 0 before 10 intervals): a 50 Hz
    inclinometer then holds back the 1 kHz streams by at most 5 ms instead of 20 ms, and
    the order stays the stamp order as long as its stamps jitter by less than
    ``lookahead`` periods.  An event that arrives after its stamp was passed is refused
    (``push`` returns None).  ``flush`` hands on everything buffered: for the end of the
    data (call it when nothing arrived for a while of wall time), when no later sample will
    ever raise the streams' stamps.
    """

    def __init__(self, streams, max_delay: float, lookahead: float = 0.75):
        self._heapq = heapq
        self.streams = set(streams)
        self.max_delay = max_delay
        self.lookahead = lookahead
        self.last: dict[str, float] = {}
        self.ahead: dict[str, float] = {}  # latest stamp + lookahead x period
        self._first: dict[str, int] = {}  # intervals seen
        self._shortest: dict[str, float] = {}
        self._margin: dict[str, float] = {}
        self.newest = -math.inf
        self.released = -math.inf
        self.hold = False  # buffer only, release nothing (a node starting up)
        self._heap: list = []
        self._seq = 0

    def __len__(self) -> int:
        return len(self._heap)

    def flush(self) -> list:
        """Hand on every buffered event, in order."""
        hq, heap = self._heapq, self._heap
        out = [hq.heappop(heap) for _ in range(len(heap))]
        if out:
            self.released = max(self.released, out[-1][0])
        return out

    def drop_stream(self, stream: str) -> None:
        """Stop waiting for ``stream`` (its later events are still merged)."""
        self.streams.discard(stream)

    def _learn(self, stream: str, t: float) -> None:
        """Margin of ``stream``: ``lookahead`` x its shortest stamp interval so far (after 10
        intervals; the shortest, not the median: a stream that starts with holes or bursts
        must not be credited with a longer period than it has)."""
        prev = self.last.get(stream)
        if prev is None or t <= prev:
            return
        n = self._first.get(stream, 0) + 1
        self._first[stream] = n
        shortest = min(self._shortest.get(stream, math.inf), t - prev)
        self._shortest[stream] = shortest
        if n >= 10:
            self._margin[stream] = self.lookahead * shortest

    def push(self, stream: str, t: float, rank: int, payload) -> list | None:
        """Buffer one event; return the releasable events as (t, rank, seq, stream, payload)."""
        if t < self.released:
            return None
        self._learn(stream, t)
        self.last[stream] = t
        self.ahead[stream] = t + self._margin.get(stream, 0.0)
        if t > self.newest:
            self.newest = t
        self._seq += 1
        self._heapq.heappush(self._heap, (t, rank, self._seq, stream, payload))
        return self._release()

    def push_many(self, stream: str, ts: list, rank: int, payloads: list) -> tuple[list, list]:
        """Buffer the events of one stream (stamps increasing) and release once: the same
        order as :meth:`push` one by one.  Returns (released events, indices refused)."""
        refused = []
        push, heap, released = self._heapq.heappush, self._heap, self.released
        learn, last = self._learn, self.last
        seq = self._seq
        t_last = None
        for i, (t, payload) in enumerate(zip(ts, payloads)):
            if t < released:
                refused.append(i)
                continue
            learn(stream, t)
            last[stream] = t
            seq += 1
            push(heap, (t, rank, seq, stream, payload))
            t_last = t
        self._seq = seq
        if t_last is None:
            return [], refused
        self.last[stream] = t_last
        self.ahead[stream] = t_last + self._margin.get(stream, 0.0)
        if t_last > self.newest:
            self.newest = t_last
        return self._release(), refused

    def discard_before(self, t: float) -> int:
        """Drop the buffered events older than ``t``; returns how many."""
        keep = [e for e in self._heap if e[0] >= t]
        n = len(self._heap) - len(keep)
        if n:
            self._heapq.heapify(keep)
            self._heap = keep
        return n

    def release(self) -> list:
        """The events releasable now (see :meth:`push`); none while ``hold`` is set."""
        return self._release()

    def _release(self) -> list:
        if self.hold:
            return []
        ahead = self.ahead
        mark = min((ahead.get(s, -math.inf) for s in self.streams), default=self.newest)
        mark = max(mark, self.newest - self.max_delay)
        out = []
        hq, heap = self._heapq, self._heap
        while heap and heap[0][0] <= mark:
            out.append(hq.heappop(heap))
        if out:
            self.released = out[-1][0]
        return out
