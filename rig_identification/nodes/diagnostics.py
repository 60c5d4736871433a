"""A node's state on ``/diagnostics``: message counts, matched readers, and each input stream
OK / WARN stale / ERROR stopped (diagnostic_msgs)."""
from __future__ import annotations

import time
from typing import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.publisher import Publisher

from .inputs import InputGuard
from .qos import DIAGNOSTICS_QOS
from .topics import DIAGNOSTICS_TOPIC


class Diagnostics:
    """Publish the node's state on ``/diagnostics`` (diagnostic_msgs/DiagnosticArray) once per
    ``period`` s.

    * One status named after the node: ``rx <topic>``, ``rejected <topic>``, ``tx <topic>``,
      ``matched <topic>`` (readers matched by this node's writer, DDS level: what a sensor
      driver waits for before it starts) plus any extra key/values; level WARN when a
      message was rejected or an input is stale, ERROR when an input stopped.
    * One status per input topic, named ``<node>: <topic>``: OK while messages arrive;
      WARN "stale" when none came for ``stale_after`` s (wall time); ERROR "stopped" after
      ``stopped_after`` s; WARN "no message yet" before the first.  Values: ``age_s`` since
      the last message, ``rate_hz`` over the last period, ``received``, ``rejected``,
      ``gaps`` (stamp gaps seen, :class:`InputGuard`) and ``last_gap`` (its stamps).
      The node parameters ``stale_after`` (0.5 s) and ``stopped_after`` (2.0 s) set the
      thresholds.
    """

    def __init__(self, node: Node, guard: InputGuard, period: float = 1.0,
                 extra: Callable[[], dict] | None = None):
        self.node, self.guard, self.extra = node, guard, extra
        for name, default in (("stale_after", 0.5), ("stopped_after", 2.0)):
            if not node.has_parameter(name):
                node.declare_parameter(name, default)
        self.stale_after = float(node.get_parameter("stale_after").value)
        self.stopped_after = float(node.get_parameter("stopped_after").value)
        self.sent: dict[str, int] = {}
        self.writers: dict[str, Publisher] = {}
        self._rx_prev: dict[str, int] = {}
        self._t_prev = time.monotonic()
        self.pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self.timer = node.create_timer(period, self.publish)

    def add_writer(self, topic: str, publisher: Publisher) -> None:
        """Report the matched-reader count of ``publisher`` as ``matched <topic>``."""
        self.writers[topic] = publisher

    def count_tx(self, topic: str, n: int = 1) -> None:
        self.sent[topic] = self.sent.get(topic, 0) + n

    def values(self) -> dict:
        g = self.guard
        out = {}
        for topic in sorted(set(g.received) | set(g.rejected)):
            out[f"rx {topic}"] = g.received.get(topic, 0)
            out[f"rejected {topic}"] = g.rejected.get(topic, 0)
        for topic in sorted(self.sent):
            out[f"tx {topic}"] = self.sent[topic]
        for topic, pub in self.writers.items():
            out[f"matched {topic}"] = pub.get_subscription_count()
        if self.extra is not None:
            out.update(self.extra())
        return out

    def input_states(self) -> dict[str, tuple[int, str, dict]]:
        """topic -> (level, message, values) of each input stream (see the class)."""
        g, now = self.guard, time.monotonic()
        dt = max(now - self._t_prev, 1e-9)
        out = {}
        for topic in sorted(g.received):
            n = g.received.get(topic, 0)
            last = g.last_arrival.get(topic)
            age = None if last is None else now - last
            if age is None:
                level, msg = DiagnosticStatus.WARN, "no message yet"
            elif age >= self.stopped_after:
                level, msg = DiagnosticStatus.ERROR, f"stopped: no message for {age:.1f} s"
            elif age >= self.stale_after:
                level, msg = DiagnosticStatus.WARN, f"stale: no message for {age:.1f} s"
            else:
                level, msg = DiagnosticStatus.OK, "ok"
            gaps = g.gaps.get(topic, [])
            rate = (n - self._rx_prev.get(topic, 0)) / dt
            vals = {"age_s": "" if age is None else f"{age:.3f}", "rate_hz": f"{rate:.1f}",
                    "received": n, "rejected": g.rejected.get(topic, 0), "gaps": len(gaps)}
            if gaps:
                vals["last_gap"] = f"{gaps[-1][0]:.6f} {gaps[-1][1]:.6f}"
            out[topic] = (level, msg, vals)
        return out

    def publish(self) -> None:
        vals = self.values()
        inputs = self.input_states()
        self._rx_prev = dict(self.guard.received)
        self._t_prev = time.monotonic()
        name = self.node.get_fully_qualified_name()
        rejected = sum(self.guard.rejected.values())
        st = DiagnosticStatus(name=name, hardware_id="rig")
        worst = max((lv for lv, _, _ in inputs.values()), default=DiagnosticStatus.OK)
        problems = [f"{t} {m.split(':')[0]}" for t, (lv, m, _) in inputs.items() if lv != DiagnosticStatus.OK]
        st.level = max(worst, DiagnosticStatus.WARN if rejected else DiagnosticStatus.OK)
        parts = ([f"{rejected} malformed message(s) dropped"] if rejected else []) + problems
        st.message = "; ".join(parts) if parts else "ok"
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        statuses = [st]
        for topic, (level, msg, v) in inputs.items():
            s = DiagnosticStatus(name=f"{name}: {topic}", hardware_id="rig", level=level, message=msg)
            s.values = [KeyValue(key=k, value=str(x)) for k, x in v.items()]
            statuses.append(s)
        arr = DiagnosticArray(status=statuses)
        arr.header.stamp = self.node.get_clock().now().to_msg()
        self.pub.publish(arr)


def diagnostic_values(status) -> dict:
    """DiagnosticStatus -> {key: int|float|str} (numbers parsed back)."""
    out: dict[str, int | float | str] = {}
    for kv in status.values:
        v = kv.value
        try:
            out[kv.key] = int(v)
        except ValueError:
            try:
                out[kv.key] = float(v)
            except ValueError:
                out[kv.key] = v
    return out
