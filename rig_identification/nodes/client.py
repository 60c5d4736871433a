"""mass_properties_client: asks the identifier for the mass properties and prints them.

Waits for the identifier's services, optionally until its buffer stops growing (the
recording has been processed), calls ~/identify_inertia and ~/estimate_cg, and prints the
identified mass properties beside the truth of a simulated experiment (latched
``/rig/sim_truth``, when a sensor driver publishes one) with the error of each entry:
% of the true value for mass and the diagonal of the tensor, % of the largest true
diagonal entry for the products of inertia, mm for the centre of gravity.

When the identifier is busy with another request's fit, the client asks again.

Exit status: 0 identified; 1 the identifier refused or failed (reason printed);
2 the identifier is not reachable (or bad command line).
"""
from __future__ import annotations

import argparse
import json
import sys
import time

KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def format_table(result: dict, truth: dict | None, cg_answer: str | None = None, name: str = "/identifier") -> str:
    """The mass-properties table (see module docstring) as text."""
    lines = []
    w = result.get("window", {})
    head = f"Mass properties identified by {name}"
    lines.append(head)
    lines.append("=" * len(head))
    if w:
        span = w.get("end", 0.0) - w.get("start", 0.0)
        rel = ""
        if "start_relative" in w:
            rel = f" ({w['start_relative']:.1f}–{w['end_relative']:.1f} s after the first IMU sample)"
        band = result.get("band_hz")
        lines.append(f"window: {span:.1f} s{rel}, {w.get('samples', 0)} samples"
                     + (f"; fit band {band[0]:.2f}–{band[1]:.2f} Hz" if band else ""))
    has_truth = truth is not None and "inertia_about_cg" in truth
    hdr = f"{'quantity':<10}{'unit':>7}{'identified':>13}{'±1σ':>10}"
    if has_truth:
        hdr += f"{'truth':>13}{'error':>12}"
    lines.append(hdr)
    lines.append("-" * len(hdr))

    def row(label, unit, value, std, true, err):
        s = f"{label:<10}{unit:>7}{value:>13}{std:>10}"
        if has_truth:
            s += f"{true:>13}{err:>12}"
        lines.append(s)

    m = result["mass"]
    mt = truth.get("mass") if has_truth else None
    row("mass", "kg", f"{m:.2f}", "given", f"{mt:.2f}" if mt is not None else "—",
        f"{100 * (m - mt) / mt:+.3f} %" if mt else "—")
    cg = result["center_of_gravity"]
    cgt = truth.get("center_of_gravity") if has_truth else None
    for k, axis in enumerate("xyz"):
        row(f"CG {axis}", "m", f"{cg[k]:.4f}", "given", f"{cgt[k]:.4f}" if cgt else "—",
            f"{1000 * (cg[k] - cgt[k]):+.1f} mm" if cgt else "—")
    J = result["inertia_about_cg"]
    std = result.get("inertia_std", {})
    Jt = truth["inertia_about_cg"] if has_truth else None
    big = max(abs(Jt["ixx"]), abs(Jt["iyy"]), abs(Jt["izz"])) if Jt else None
    for k in KEYS:
        diag = k in ("ixx", "iyy", "izz")
        err = "—"
        if Jt is not None:
            ref = abs(Jt[k]) if diag else big
            err = f"{100 * (J[k] - Jt[k]) / ref:+.3f} %" + ("" if diag else "*")
        row(k.capitalize(), "kg·m²", f"{J[k]:.2f}", f"{std[k]:.2f}" if k in std else "—",
            f"{Jt[k]:.2f}" if Jt else "—", err)
    lines.append("mass and CG: the known values of rig.yaml (the dynamic experiment identifies the tensor)")
    if has_truth:
        lines.append("error: % of the true value; * products of inertia: % of the largest true diagonal entry")
    for wd in result.get("weakly_determined", [])[:1]:
        if isinstance(wd, dict) and wd.get("text"):
            lines.append("note: " + wd["text"])
    for warning in result.get("warnings", []):
        lines.append("warning: " + warning)
    if cg_answer is not None:
        lines.append(f"centre-of-gravity estimate (~/estimate_cg): {cg_answer}")
    return "\n".join(lines)


def _error_text(message: str) -> str:
    try:
        d = json.loads(message)
        return d.get("error", message) if isinstance(d, dict) else message
    except ValueError:
        return message


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="mass_properties_client", description=__doc__.split("\n\n")[0],
                                 epilog="ROS arguments may follow --ros-args.")
    ap.add_argument("--identifier", default="/identifier", help="identifier node (default /identifier)")
    ap.add_argument("--timeout", type=float, default=60.0, help="wait this long for the services, s (default 60)")
    ap.add_argument("--fit-timeout", type=float, default=300.0, help="wait this long for the fit, s (default 300)")
    ap.add_argument("--wait-stable", type=float, default=0.0, metavar="S",
                    help="first wait until the identifier has received no new sample for S s")
    ap.add_argument("--truth-timeout", type=float, default=3.0, help="wait this long for /rig/sim_truth, s")
    ap.add_argument("--json", action="store_true", help="print the identifier's answer as one JSON object")
    import rclpy
    from rclpy.utilities import remove_ros_args
    argv = list(sys.argv if argv is None else argv)
    args = ap.parse_args(remove_ros_args(argv)[1:])
    rclpy.init(args=argv)
    from rclpy.node import Node
    from std_msgs.msg import String
    from std_srvs.srv import Trigger

    from . import common
    node = Node("mass_properties_client")
    log = lambda s: print(s, file=sys.stderr, flush=True)  # noqa: E731
    base = args.identifier.rstrip("/")
    truth: dict = {}

    def on_truth(msg):
        try:
            truth.update(json.loads(msg.data))
        except ValueError:
            pass
    node.create_subscription(String, common.TRUTH_TOPIC, on_truth, common.LATCHED_QOS)
    cli_id = node.create_client(Trigger, f"{base}/identify_inertia")
    cli_cg = node.create_client(Trigger, f"{base}/estimate_cg")
    cli_st = node.create_client(Trigger, f"{base}/status")

    def call(cli, timeout):
        fut = cli.call_async(Trigger.Request())
        rclpy.spin_until_future_complete(node, fut, timeout_sec=timeout)
        if not fut.done():
            cli.remove_pending_request(fut)
            return None
        return fut.result()

    try:
        if not cli_id.wait_for_service(timeout_sec=args.timeout):
            log(f"mass_properties_client: error: service {base}/identify_inertia not available "
                f"after {args.timeout:.0f} s (is the identifier running, same ROS_DOMAIN_ID?)")
            return 2
        if args.wait_stable > 0 and cli_st.wait_for_service(timeout_sec=5.0):
            last, since, t_end = None, time.monotonic(), time.monotonic() + args.timeout
            while time.monotonic() < t_end:
                r = call(cli_st, 5.0)
                n = json.loads(r.message).get("wrench") if r is not None else None
                if n != last:
                    last, since = n, time.monotonic()
                elif n and time.monotonic() - since >= args.wait_stable:
                    break
                time.sleep(0.2)
            log(f"identifier buffer: {last} wrench samples")
        t0 = time.monotonic()
        while True:
            r = call(cli_id, max(1.0, args.fit_timeout - (time.monotonic() - t0)))
            busy = r is not None and not r.success and _error_text(r.message).startswith("busy")
            if not busy or time.monotonic() - t0 > args.fit_timeout:
                break
            log("the identifier is busy with another fit; asking again in 1 s")
            time.sleep(1.0)
        if r is None:
            log(f"mass_properties_client: error: no answer from {base}/identify_inertia "
                f"within {args.fit_timeout:.0f} s")
            return 2
        log(f"identify_inertia answered in {time.monotonic() - t0:.1f} s")
        cg = call(cli_cg, 10.0) if cli_cg.wait_for_service(timeout_sec=2.0) else None
        cg_text = None if cg is None else (cg.message if cg.success else _error_text(cg.message))
        end = time.monotonic() + args.truth_timeout
        while not truth and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
        if not r.success:
            log(f"mass_properties_client: identification failed: {_error_text(r.message)}")
            return 1
        result = json.loads(r.message)
        if args.json:
            print(json.dumps(result))
        else:
            print(format_table(result, truth or None, cg_text, base))
        return 0
    except KeyboardInterrupt:
        return 130
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
