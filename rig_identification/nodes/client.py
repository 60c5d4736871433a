"""mass_properties_client: the identifier's services from the command line (a lab tool).

Verbs (ROS arguments may follow ``--ros-args``; ``--identifier NAME`` picks the node):

  mass_properties_client [identify] [--json] [--wait-stable S] [--fit-timeout S]
      waits for the identifier's services, optionally until its buffer stops growing (the
      recording has been processed), calls ~/identify_rig_model (the rig model of
      ``rig-identify inertia``: every sensor an output, the mass, CG and tensor fitted together,
      the CG's prior the last cg-estimate, over the identifier's window of its raw streams) and
      prints (:func:`format_rig_model`) the verdict first, the conventions of ``rig-identify
      inertia`` (body frame, SI units, products with the vehicle-dynamics sign), the tensor with
      σ and the Cramér–Rao bound beside the truth of a simulated experiment (latched
      ``/rig/sim_truth``, when a sensor driver publishes one) with the error of each entry (% of
      the true value for the moments, % of the largest true moment for the products), the
      mass, the CG from the static test, the run alone and both, and each channel's residual
      over its noise.  When the identifier is busy with another request's fit, the client asks
      again.
  mass_properties_client cg-capture baseline|dummy [--json]
      the static centre-of-gravity experiment, steps 1 and 2: ~/capture_cg_baseline
      (body at rest without the dummy mass) or ~/capture_cg_dummy (with it, at rig.yaml
      dummy_mass.position): the identifier averages the last cg_capture_seconds of the raw
      streams; prints the seconds averaged and the cable tensions (N, rig.yaml order).
  mass_properties_client cg-estimate [--json] [--write-rig OUT.yaml [--rig RIG] [--force]]
      step 3: ~/estimate_cg; prints the centre of gravity (body frame, m) with its standard
      deviation (and the error against /rig/sim_truth when there is one, mm).  The estimate
      is also published on /rig/mass_properties.  ``--write-rig OUT.yaml`` writes a copy of
      the rig description with ``body.center_of_gravity`` set to the estimate (atomically;
      the comment lines of ``rig-identify cg --write-rig``, the same core:
      ``statics.handover.rig_with_cg_text``): RIG is the identifier's ``rig`` parameter unless
      ``--rig`` names it (a rig.yaml, a recording folder or an experiment file; its body.mass
      must be the identifier's); an existing OUT is replaced only with ``--force``.  The
      dynamic experiment's tracker, preprocessor and identifier then start with
      ``rig:=OUT.yaml``.
  mass_properties_client status [--json]
      ~/status: samples buffered by the identifier.

Exit status: 0 done; 1 the identifier refused or failed (its reason printed, e.g. "capture
the baseline and dummy states first"); 2 the identifier is not reachable (or bad command line).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import rclpy
import yaml
from rclpy.node import Node
from rclpy.parameter_client import AsyncParameterClient
from rclpy.utilities import remove_ros_args
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ..io.atomic import atomic_write_text
from ..io.export import BODY, convention_lines
from ..io.rig import RigError
from ..io.verdict import PACKAGE, package_version
from ..statics.handover import CgResultError, cg_result_from_dict, check_rig_target, rig_with_cg_text
from .parameters import load_rig_source
from .qos import LATCHED_QOS, SERVICE_SETTLE_SECONDS
from .topics import TRUTH_TOPIC

#: the tensor entries in the order of every rig-identify table and option (moments, then products)
KEYS = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
PRODUCTS = ("ixy", "ixz", "iyz")
#: beside an entry the recording does not determine (the answer's "undetermined")
NOT_DETERMINED = "not determined"


def format_rig_model(answer: dict, truth: dict | None, name: str = "/identifier") -> str:
    """Text for the answer of ~/identify_rig_model (``RigModelResult.to_dict``, the JSON of
    ``rig-identify inertia --json``): the verdict first, the conventions, the moments and
    products of inertia about the CG (products with the vehicle-dynamics sign) with σ and the
    Cramér–Rao bound (and the error against ``truth`` when given; "not determined" beside an entry
    of the answer's ``undetermined``), the mass, the centre of gravity
    from the static test, the run alone and both, and each channel's residual over its noise."""
    head = f"Mass properties identified by {name} (the rig model, every sensor an output)"
    lines = [head, "=" * len(head), f"verdict: {answer['verdict']}"]
    lines += convention_lines(BODY)
    J, sd, crb = answer["inertia_about_cg"], answer["inertia_std"], answer["inertia_crb"]
    Jt = (truth or {}).get("inertia_about_cg")
    big = max(abs(Jt["ixx"]), abs(Jt["iyy"]), abs(Jt["izz"])) if Jt else None
    hdr = f"{'quantity':<10}{'identified':>12}{'±1σ':>9}{'CRB':>9}" + (f"{'truth':>11}{'error':>11}" if Jt else "")
    lines += [hdr + "   (kg·m²)", "-" * len(hdr)]
    undetermined = set(answer.get("undetermined") or ())
    for k in KEYS:
        sign = -1.0 if k in PRODUCTS else 1.0     # the table's products: vehicle-dynamics sign, Ixy = −ixy
        row = f"{'I' + k[1:]:<10}{sign * J[k] + 0.0:>12.2f}{sd[k]:>9.3g}{crb[k]:>9.3g}"
        if Jt:
            ref = big if k in PRODUCTS else abs(Jt[k])
            row += f"{sign * Jt[k] + 0.0:>11.2f}{sign * 100 * (J[k] - Jt[k]) / ref + 0.0:>+10.3f}%"
        lines.append(row + (f"  {NOT_DETERMINED}" if k in undetermined else ""))
    if answer["verdict"] in ("not_identifiable", "failed"):
        lines.append("no entry above is an estimate to use (verdict " + answer["verdict"] + ")")
    lines.append(f"mass {answer['mass']:.2f} ± {answer['mass_std']:.2f} kg (fitted, the scale's value its prior)")
    c = answer["center_of_gravity"]
    for label, key, what in (("static", "static", c.get("static_source", "")), ("dynamic", "dynamic", "the run alone"),
                             ("combined", "combined", "the tensor is about it")):
        v, s_ = c[key], c[key + "_std"]
        if v is None or v[0] is None:
            continue
        lines.append(f"CG {label:<9} (" + ", ".join(f"{1e3 * x:.1f}" if x is not None else "—" for x in v)
                     + ") ± (" + ", ".join(f"{1e3 * x:.2g}" if x is not None else "—" for x in s_) + f") mm  {what}")
    lines.append("residual over the noise: " + ", ".join(f"{k} {v:.2f}" for k, v in answer["residual_level"].items()))
    lines += [f"warning: {w}" for w in answer.get("warnings", [])]
    return "\n".join(lines)


def error_text(message: str) -> str:
    """The ``error`` of a service's JSON answer (or the answer itself when it is not JSON)."""
    try:
        d = json.loads(message)
        return d.get("error", message) if isinstance(d, dict) else message
    except ValueError:
        return message


def format_capture(which: str, answer: dict) -> str:
    """Text for the answer of ~/capture_cg_baseline or ~/capture_cg_dummy."""
    tensions = answer.get("tensions")
    lines = [f"captured the {which} state: {answer.get('seconds', 0.0):.1f} s of data averaged"]
    if tensions:
        lines.append("cable tensions (rig.yaml order): " + ", ".join(f"{x:.1f}" for x in tensions) + " N")
    lines += [f"warning: {w}" for w in answer.get("warnings", [])]
    lines.append("next: fix the dummy mass, let the body come to rest, then `mass_properties_client cg-capture "
                 "dummy`" if which == "baseline" else "next: `mass_properties_client cg-estimate`")
    return "\n".join(lines)


def format_cg(answer: dict, truth: dict | None, name: str = "/identifier") -> str:
    """Text for the answer of ~/estimate_cg (a ``statics.CgResult.to_dict()``), with the error
    against ``truth["center_of_gravity"]`` (mm) when given."""
    head = f"Centre of gravity estimated by {name} (frame {answer.get('frame', 'body')})"
    cg, sd = answer["center_of_gravity"], answer.get("center_of_gravity_std") or [None] * 3
    true_cg = (truth or {}).get("center_of_gravity")
    hdr = f"{'quantity':<10}{'unit':>6}{'estimate':>12}{'±1σ':>10}" + (f"{'truth':>12}{'error':>12}" if true_cg else "")
    lines = [head, "=" * len(head), hdr, "-" * len(hdr)]
    for k, axis in enumerate("xyz"):
        row = f"{'CG ' + axis:<10}{'m':>6}{cg[k]:>12.5f}" + (f"{sd[k]:>10.5f}" if sd[k] is not None else f"{'—':>10}")
        if true_cg:
            row += f"{true_cg[k]:>12.5f}{1000 * (cg[k] - true_cg[k]):>+9.2f} mm"
        lines.append(row)
    m, m_lc, m_lc_sd = answer.get("mass"), answer.get("mass_from_load_cells"), answer.get("mass_from_load_cells_std")
    if m is not None:
        lines.append(f"{'mass':<10}{'kg':>6}{m:>12.2f}{'given':>10}")
    if m_lc is not None:
        sd_text = f"{m_lc_sd:>10.3f}" if m_lc_sd is not None else f"{'—':>10}"
        lines.append(f"{'mass (LC)':<10}{'kg':>6}{m_lc:>12.3f}{sd_text}   from the load cells")
    lines += [f"warning: {w}" for w in answer.get("warnings", [])]
    lines.append("before the dynamic experiment: `cg-estimate --write-rig OUT.yaml` writes a copy of rig.yaml with "
                 "this body.center_of_gravity (start the nodes with rig:=OUT.yaml); `cg-estimate --json > cg.json` "
                 "saves it for `rig-identify inertia RUN --cg cg.json`")
    return "\n".join(lines)


class IdentifierClient:
    """std_srvs/Trigger calls to the identifier ``base`` (``/identifier``) from ``node``."""

    def __init__(self, node: Node, base: str):
        self.node, self.base = node, base.rstrip("/")
        self.clients: dict = {}

    def client(self, service: str):
        if service not in self.clients:
            self.clients[service] = self.node.create_client(Trigger, f"{self.base}/{service}")
        return self.clients[service]

    def wait(self, service: str, timeout: float) -> bool:
        """True once ``<base>/<service>`` is available (within ``timeout`` s), and
        :data:`~.qos.SERVICE_SETTLE_SECONDS` more for the server's side of the discovery."""
        if not self.client(service).wait_for_service(timeout_sec=timeout):
            return False
        end = time.monotonic() + SERVICE_SETTLE_SECONDS
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=max(0.0, end - time.monotonic()))
        return True

    def call(self, service: str, timeout: float) -> Trigger.Response | None:
        """Call ``<base>/<service>``; the response, or None without an answer within ``timeout`` s."""
        cli = self.client(service)
        fut = cli.call_async(Trigger.Request())
        rclpy.spin_until_future_complete(self.node, fut, timeout_sec=timeout)
        if not fut.done():
            cli.remove_pending_request(fut)
            return None
        return fut.result()


def parser(verb: str) -> argparse.ArgumentParser:
    """The command line of ``verb`` (one of :data:`VERBS`)."""
    prog = "mass_properties_client" + ("" if verb == "identify" else f" {verb}")
    ap = argparse.ArgumentParser(prog=prog, description=VERBS[verb], epilog=EPILOG,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    if verb == "cg-capture":
        ap.add_argument("state", choices=("baseline", "dummy"),
                        help="baseline: the body at rest without the dummy mass; dummy: with it")
    ap.add_argument("--version", action="version", version=f"mass_properties_client ({PACKAGE}) {package_version()}")
    ap.add_argument("--identifier", default="/identifier", help="identifier node (default /identifier)")
    ap.add_argument("--timeout", type=float, default=60.0, help="wait this long for the services, s (default 60)")
    ap.add_argument("--json", action="store_true", help="print the identifier's answer as one JSON object")
    if verb == "cg-estimate":
        ap.add_argument("--write-rig", metavar="OUT.yaml",
                        help="also write a copy of the rig description with body.center_of_gravity set to the "
                             "estimate (as rig-identify cg --write-rig)")
        ap.add_argument("--rig", metavar="RIG",
                        help="the rig description to copy (rig.yaml, recording folder or experiment file; default: "
                             "the identifier's rig parameter)")
        ap.add_argument("--force", action="store_true", help="let --write-rig replace an existing file")
    if verb in ("identify", "cg-estimate"):
        ap.add_argument("--truth-timeout", type=float, default=1.0 if verb == "cg-estimate" else 3.0,
                        help="wait this long for /rig/sim_truth (simulations only), s")
    if verb == "identify":
        ap.add_argument("--fit-timeout", type=float, default=300.0, help="wait this long for the fit, s (default 300)")
        ap.add_argument("--wait-stable", type=float, default=0.0, metavar="S",
                        help="first wait until the identifier has received no new sample for S s")
    return ap


VERBS = {
    "identify": "Fit the rig model (rig-identify inertia's core) to the identifier's buffered raw streams\n"
                "(~/identify_rig_model) and print the mass, CG and inertia tensor, verdict first.",
    "cg-capture": "Static CG experiment, step 1 or 2: capture the body at rest without (baseline) or with "
                  "(dummy) the dummy mass.",
    "cg-estimate": "Static CG experiment, step 3: estimate the centre of gravity from the two captured states.",
    "status": "Print the identifier's buffer status (~/status).",
}

#: every help's closing text: the verbs, each with what it does, and the static CG procedure
EPILOG = ("verbs (mass_properties_client VERB --help for each):\n"
          "  [identify]                 fit the rig model; print the mass, CG and tensor, verdict first\n"
          "  cg-capture baseline|dummy  CG steps 1, 2: capture the body at rest without / with the dummy\n"
          "  cg-estimate                CG step 3: the centre of gravity and its σ from the two captures\n"
          "  status                     samples buffered by the identifier\n"
          "\nthe static centre of gravity, the body at rest each time (docs/ros.md):\n"
          "  mass_properties_client cg-capture baseline     # without the dummy mass\n"
          "  mass_properties_client cg-capture dummy        # with it, at rig.yaml dummy_mass.position\n"
          "  mass_properties_client cg-estimate --write-rig rig_with_cg.yaml\n"
          "\nROS arguments may follow --ros-args.  Exit status: 0 done; 1 the identifier refused or failed\n"
          "(its reason printed); 2 the identifier is not reachable, or a bad command line.")

def main(argv=None) -> int:
    argv = list(sys.argv if argv is None else argv)
    user = remove_ros_args(argv)[1:]
    verb = "identify"
    if user and user[0] in VERBS:
        verb, user = user[0], user[1:]
    args = parser(verb).parse_args(user)
    rclpy.init(args=argv)
    node = Node("mass_properties_client")
    try:
        return run(verb, args, node)
    except KeyboardInterrupt:
        return 130
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def truth_listener(node: Node) -> dict:
    """A dict filled with the latched /rig/sim_truth (JSON) once it arrives (spin ``node``)."""
    truth: dict = {}

    def on_truth(msg):
        try:
            truth.update(json.loads(msg.data))
        except ValueError:
            pass
    node.create_subscription(String, TRUTH_TOPIC, on_truth, LATCHED_QOS)
    return truth


def wait_truth(node: Node, truth: dict, timeout: float) -> None:
    end = time.monotonic() + timeout
    while not truth and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)


def run(verb: str, args, node: Node) -> int:
    """Carry out ``verb`` (see the module docstring); the exit status."""
    idf = IdentifierClient(node, args.identifier)
    first = {"identify": "identify_rig_model", "cg-capture": f"capture_cg_{getattr(args, 'state', '')}",
             "cg-estimate": "estimate_cg", "status": "status"}[verb]
    truth = truth_listener(node) if verb in ("identify", "cg-estimate") else {}
    if not idf.wait(first, args.timeout):
        log(f"mass_properties_client: error: service {idf.base}/{first} not available "
            f"after {args.timeout:.0f} s (is the identifier running, same ROS_DOMAIN_ID?)")
        return 2
    if verb == "identify":
        return identify(args, node, idf, truth)
    target = None
    if getattr(args, "write_rig", None):
        try:   # before the estimate, as rig-identify cg checks before its fit
            target = RigTarget.resolve(args, node, idf)
        except (RigError, CgResultError) as e:
            log(f"mass_properties_client: error: {e}")
            return 2
    wait = 60.0
    r = idf.call(first, wait)
    if r is None:
        log(f"mass_properties_client: error: no answer from {idf.base}/{first} within {wait:.0f} s")
        return 2
    if not r.success:
        log(f"mass_properties_client: {first} refused: {error_text(r.message)}")
        return 1
    answer = json.loads(r.message)
    if target is not None:
        try:
            answer["written_rig"] = target.write(answer, idf.base)
        except (RigError, CgResultError, OSError) as e:
            log(f"mass_properties_client: error: {e}")
            return 2
    if args.json:
        print(json.dumps(answer))
    elif verb == "cg-capture":
        print(format_capture(args.state, answer))
    elif verb == "cg-estimate":
        wait_truth(node, truth, args.truth_timeout)
        print(format_cg(answer, truth or None, idf.base))
        if target is not None:
            print(f"written: {answer['written_rig']} (rig description {target.source} with this "
                  "body.center_of_gravity): start tracker, preprocessor and identifier with "
                  f"rig:={answer['written_rig']} for the dynamic experiment")
    else:
        print("\n".join(f"{k}: {v}" for k, v in answer.items()))
    return 0


def rig_parameter(node: Node, base: str, timeout: float) -> str | None:
    """The identifier ``base``'s ``rig`` parameter (its parameter service), or None when it
    does not answer within ``timeout`` s or the parameter is empty."""
    cli = AsyncParameterClient(node, base)
    if not cli.wait_for_services(timeout_sec=timeout):
        return None
    fut = cli.get_parameters(["rig"])
    rclpy.spin_until_future_complete(node, fut, timeout_sec=timeout)
    if not fut.done() or fut.result() is None or not fut.result().values:
        return None
    return fut.result().values[0].string_value or None


class RigTarget:
    """``cg-estimate --write-rig``: the rig description to copy and where to write the copy."""

    def __init__(self, out: Path, source: str, force: bool):
        self.out, self.source, self.force = out, source, force
        self.rig = load_rig_source(source)
        p = Path(source)
        self.rig_file = p / "rig.yaml" if p.is_dir() else p
        self.recordings = [p] if p.is_dir() else []
        check_rig_target(out, force, self.recordings)

    @classmethod
    def resolve(cls, args, node: Node, idf: IdentifierClient) -> "RigTarget":
        """From the options: ``--rig``, else the identifier's ``rig`` parameter.  Raises
        RigError (unreadable rig, no parameter) or CgResultError (the target exists, ...)."""
        source = args.rig or rig_parameter(node, idf.base, 10.0)
        if not source:
            raise RigError(f"--write-rig: the rig parameter of {idf.base} could not be read; name the rig "
                           "description to copy with --rig RIG")
        return cls(Path(args.write_rig), source, args.force)

    def write(self, answer: dict, base: str) -> str:
        """Write the copy with the CG of ``answer`` (~/estimate_cg's JSON); returns its path.
        Raises CgResultError when the answer is not a CG result or describes another body."""
        saved = cg_result_from_dict(answer, f"{base}/estimate_cg")
        if saved.mass is not None and abs(saved.mass - self.rig.mass) > 1e-9 * max(self.rig.mass, 1.0):
            raise CgResultError(f"{self.source}: body.mass {self.rig.mass:g} kg, but {base} estimated the CG of a "
                                f"{saved.mass:g} kg body: another rig description (name the identifier's with --rig)")
        check_rig_target(self.out, self.force, self.recordings)   # again: the capture took a while
        original = None   # a rig.yaml's leading comment lines are kept (not an experiment file's)
        if self.rig_file.is_file():
            text = self.rig_file.read_text(encoding="utf-8")
            d = yaml.safe_load(text)
            original = text if isinstance(d, dict) and "cables" in d else None
        created = datetime.now(timezone.utc).isoformat(timespec="seconds")
        atomic_write_text(self.out, rig_with_cg_text(
            self.rig, saved, [f"the static states captured by {base} (capture_cg_baseline, capture_cg_dummy)"],
            created, original, by=f"mass_properties_client cg-estimate ({base}/estimate_cg)"))
        return str(self.out)


def wait_stable(args, idf: IdentifierClient) -> None:
    """``--wait-stable S``: wait (at most ``--timeout``) until the identifier's buffer has received
    no new sample for S s."""
    if args.wait_stable > 0 and idf.wait("status", 5.0):
        last, since, t_end = None, time.monotonic(), time.monotonic() + args.timeout
        while time.monotonic() < t_end:
            r = idf.call("status", 5.0)
            n = json.loads(r.message).get("imu") if r is not None else None
            if n != last:
                last, since = n, time.monotonic()
            elif n and time.monotonic() - since >= args.wait_stable:
                break
            time.sleep(0.2)
        log(f"identifier buffer: {last} IMU samples")


def identify(args, node: Node, idf: IdentifierClient, truth: dict) -> int:
    """The ``identify`` verb: the rig model's fit (asked again while the identifier is busy), its
    text (:func:`format_rig_model`) or JSON."""
    wait_stable(args, idf)
    t0 = time.monotonic()
    while True:
        r = idf.call("identify_rig_model", max(1.0, args.fit_timeout - (time.monotonic() - t0)))
        busy = r is not None and not r.success and error_text(r.message).startswith("busy")
        if not busy or time.monotonic() - t0 > args.fit_timeout:
            break
        log("the identifier is busy with another fit; asking again in 1 s")
        time.sleep(1.0)
    if r is None:
        log(f"mass_properties_client: error: no answer from {idf.base}/identify_rig_model "
            f"within {args.fit_timeout:.0f} s")
        return 2
    log(f"identify_rig_model answered in {time.monotonic() - t0:.1f} s")
    wait_truth(node, truth, args.truth_timeout)
    if not r.success:
        log(f"mass_properties_client: identification failed: {error_text(r.message)}")
        return 1
    result = json.loads(r.message)
    if args.json:
        print(json.dumps(result))
    else:
        print(format_rig_model(result, truth or None, idf.base))
    return 0


if __name__ == "__main__":
    sys.exit(main())
