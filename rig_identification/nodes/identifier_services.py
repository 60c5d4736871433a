"""The identifier's services (std_srvs/Trigger, JSON answers), on a node of their own spun by a
MultiThreadedExecutor in a background thread.

The rclpy 7.1.6 EventsExecutor ignores callback groups, runs only one callback at a time and
cannot run ``async`` service callbacks (rclpy issue #1473, fixed in 7.1.11), so a fit inside a
service callback of the identifier node would stop its message flow.  The services therefore
live on ``<name>_services`` (service names ``/<name>/identify_rig_model`` ...) with a
ReentrantCallbackGroup: a fit runs in its own thread while the identifier keeps receiving, and
a second request during a fit is answered "busy" at once.
"""
from __future__ import annotations

import threading
from typing import Protocol

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from std_srvs.srv import Trigger

from .messages import to_json


class ServiceOwner(Protocol):
    """What :class:`IdentifierServices` needs of its owner (the identifier node): the node's
    name, namespace, context and logger, the lock ``busy`` and the calls its services make."""

    busy: threading.Lock

    @property
    def context(self) -> Context: ...

    def get_name(self) -> str: ...

    def get_namespace(self) -> str: ...

    def get_fully_qualified_name(self) -> str: ...

    def get_logger(self) -> RcutilsLogger: ...

    def estimate_cg(self) -> dict: ...

    def capture_cg(self, which: str) -> dict: ...

    def diagnose(self) -> dict: ...

    def identify_rig_model(self) -> dict: ...

    def status(self) -> dict: ...


class IdentifierServices(Node):
    """The identifier's services, on their own node and executor thread (see the module docstring).

    owner: the identifier node, whose ``identify_rig_model``, ``estimate_cg``,
    ``capture_cg``, ``diagnose`` and ``status`` the services call, one at a time (``owner.busy``, a lock)."""

    def __init__(self, owner: ServiceOwner):
        super().__init__(f"{owner.get_name()}_services", namespace=owner.get_namespace(),
                         context=owner.context, start_parameter_services=False)
        self.owner = owner
        base = owner.get_fully_qualified_name()
        group = ReentrantCallbackGroup()
        srv = lambda name, cb: self.create_service(Trigger, f"{base}/{name}", cb, callback_group=group)  # noqa: E731
        self.trigger_services = [
            srv("estimate_cg", self.on_estimate_cg),
            srv("capture_cg_baseline",
                lambda rq, rs: self._guarded_call(rs, lambda: owner.capture_cg("baseline"), "capture_cg_baseline")),
            srv("capture_cg_dummy",
                lambda rq, rs: self._guarded_call(rs, lambda: owner.capture_cg("dummy"), "capture_cg_dummy")),
            srv("status", self.on_status),
            srv("diagnose", lambda rq, rs: self._guarded_call(rs, owner.diagnose, "diagnose")),
            srv("identify_rig_model",
                lambda rq, rs: self._guarded_call(rs, owner.identify_rig_model, "identify_rig_model"))]
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def start(self) -> None:
        self._thread = threading.Thread(target=self._spin, name="identifier-services", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        ex = MultiThreadedExecutor(num_threads=3, context=self.context)
        ex.add_node(self)
        try:
            while self.context.ok() and not self._stop.is_set():
                ex.spin_once(timeout_sec=0.2)
        except Exception:  # context shut down under our feet
            if self.context.ok():
                raise
        finally:
            ex.shutdown(timeout_sec=1.0)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=3.0)

    def on_estimate_cg(self, request, response):
        return self._guarded_call(response, self.owner.estimate_cg, "estimate_cg")

    def _guarded_call(self, response, action, what: str):
        """Run a fit or a CG step, one at a time: a call while another runs is answered
        "busy"; user errors (FitWindowError, RigFitError, StaticsError: ValueErrors) come back as
        JSON errors; a bug is logged and answered, never kills the node."""
        if not self.owner.busy.acquire(blocking=False):
            response.success = False
            response.message = to_json({"error": "busy: a fit is already running; call again when it ends"})
            return response
        try:
            response.message = to_json(action())
            response.success = True
        except ValueError as e:  # StaticsError is a ValueError
            self.owner.get_logger().warn(f"{what}: {e}")
            response.success = False
            response.message = to_json({"error": str(e)})
        except Exception as e:  # a bug must not kill the node
            self.owner.get_logger().error(f"{what} failed: {type(e).__name__}: {e}")
            response.success = False
            response.message = to_json({"error": f"internal error: {type(e).__name__}: {e}"})
        finally:
            self.owner.busy.release()
        return response

    def on_status(self, request, response):
        response.success = True
        response.message = to_json(self.owner.status())
        return response
