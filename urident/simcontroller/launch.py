"""The simulated controller built from parsed options and served until a signal stops it.

The options themselves are the command line's (:mod:`urident.cli.cmd_sim_controller`: ``urident
sim-controller`` and ``python -m urident.simcontroller``).
"""

from __future__ import annotations

import argparse
import ipaddress
import signal
import socket
import sys

from urident.errors import ConfigError

START_NEAR_OFFSET_RAD = 0.05  # small, so the approach is short but still exercised


def loopback_problem(host: str) -> str | None:
    """Why ``host`` is not a loopback-only address, or None when every address it names is."""
    try:
        addresses = {info[4][0] for info in socket.getaddrinfo(host, None, socket.AF_INET)}
    except (socket.gaierror, UnicodeError) as exc:
        return f"cannot resolve it ({exc})"
    outside = sorted(a for a in addresses if not ipaddress.ip_address(a).is_loopback)
    if outside:
        return f"it binds {', '.join(outside)}, which is not a loopback address"
    return None


def check_bind_address(host: str, allow_remote: bool) -> str | None:
    """Refuse a non-loopback ``--host`` unless ``--allow-remote``; returns the warning to print
    when it is allowed."""
    problem = loopback_problem(host)
    if problem is None:
        return None
    if not allow_remote:
        raise ConfigError(f"--host {host}: {problem}; the simulated controller serves loopback "
                          f"only (pass --allow-remote to expose it to other machines)")
    return (f"warning: --allow-remote: the simulated controller on {host} is reachable from other "
            f"machines; anyone who can reach it can drive it")


def start_near(path: str, spec) -> list[float]:
    """Initial joint positions a small offset from the start of trajectory file ``path``."""
    import numpy as np

    from urident.excitation import load_trajectory

    traj = load_trajectory(path)
    if traj.robot != spec.name:
        raise ConfigError(f"--start-near {path}: trajectory is for robot '{traj.robot}', "
                          f"not '{spec.name}'")
    q = np.asarray(traj.trajectory.q_start, dtype=float) + START_NEAR_OFFSET_RAD
    # Toward the middle of the range where the offset would leave it.
    over = q > spec.q_max
    q[over] -= 2 * START_NEAR_OFFSET_RAD
    return [float(x) for x in q]


def build_server(args: argparse.Namespace):
    """Controller + server from parsed options; raises UridentError subclasses on bad input."""
    from urident.model import load_robot
    from urident.simcontroller.controller import Controller, ControllerConfig, parse_version
    from urident.simcontroller.faults import parse_fault
    from urident.simcontroller.server import SimControllerServer

    spec = load_robot(args.robot)
    faults = [parse_fault(f) for f in args.fault]
    if args.controller_version is None:
        version = parse_version(".".join(str(v) for v in spec.controller_version))
    else:
        version = parse_version(args.controller_version)
    generation = "cb3" if version[0] < 5 else "e-series"
    if generation != spec.generation:
        raise ConfigError(f"--version {'.'.join(map(str, version[:3]))} is for {generation} controllers "
                          f"but robot '{spec.name}' is {spec.generation}")
    initial_q = None if args.initial_q is None else list(args.initial_q)  # checked by options.joint_vector
    if getattr(args, "start_near", None):
        initial_q = start_near(args.start_near, spec)
    config = ControllerConfig(spec=spec, version=version, faults=faults, seed=args.seed,
                              effects_path=args.effects, initial_q=initial_q)
    controller = Controller(config)
    server = SimControllerServer(controller, host=args.host)
    server.verbose = controller.script.verbose = bool(getattr(args, "verbose", False))
    return server


def serve(args: argparse.Namespace) -> int:
    """Bind, print the ready line, run until SIGINT/SIGTERM; print loop statistics at the end."""
    from urident.simcontroller.server import format_stats, raise_priority

    warning = check_bind_address(args.host, bool(getattr(args, "allow_remote", False)))
    if warning:
        print(warning, file=sys.stderr, flush=True)
    priority = "normal priority" if args.no_realtime else raise_priority()
    server = build_server(args)
    server.bind()
    controller = server.controller
    signal.signal(signal.SIGTERM, server.request_stop)
    signal.signal(signal.SIGINT, server.request_stop)
    controller.log(f"{controller.spec.name}, controller {'.'.join(map(str, controller.version))} at "
                   f"{controller.rate_hz:g} Hz on {args.host} ({priority})"
                   + (f", faults {', '.join(f.spec for f in controller.faults.faults)}"
                      if controller.faults.faults else ""))
    stats = server.serve_forever(ready_message=f"listening on {args.host}")
    print(format_stats(stats), flush=True)
    controller.log(f"stopped after {stats['cycles']} cycles, {stats['late_cycles']} late "
                   f"({stats['late_cycle_pct']:.3f} %), CPU {stats['cpu_pct']:.1f} %")
    return 0
