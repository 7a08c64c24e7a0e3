"""``servodesk tune``: tune a drive from the command line (docs/tuning.md, docs/api.md).

    servodesk tune --node-id 5 --profile lecsn-t --mode basic --travel 0.5 --torque-limit 100
    servodesk tune --node-id 5 --travel 0.5 --enable --store --json
    servodesk tune --node-id 5 --undo before

The axis moves inside the travel window while the drive tunes: its total width in revolutions,
centred on where the axis stands (``--travel 0.5``: +-0.25 rev). This process is the operator:
it sends the dead-man heartbeat itself, so if it hangs the axis stops; Ctrl-C stops the tuning
and the motion (the gains from before are put back). ``--enable`` switches the servo on first
(otherwise a drive that is not in Operation enabled is refused). Nothing is stored unless
``--store`` is given.
``--undo before|defaults`` only returns the gains (no tuning).

Exit codes: 0 done, 1 the tuning failed (the drive's code, decoded, or servodesk's reason),
2 bad input or a refusal before anything moved (nothing to tune, servo off, window beyond the
software limits).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import math
import sys
from typing import Any

from servodesk.cli.backup import _bus_options, _Context, _dump, _run, client_id
from servodesk.errors import ValidationError

#: Heartbeat period of this process as the dead-man's operator [s].
HEARTBEAT_S = 0.05


def register(sub: Any) -> None:
    p = sub.add_parser(
        "tune",
        help="one-touch tuning of a drive (moves the axis inside a travel window)",
        description=__doc__.split("\n\n")[2] if __doc__ else None,
    )
    p.add_argument(
        "--mode", choices=["low", "basic", "high"], default="basic", help="response mode"
    )
    p.add_argument(
        "--travel",
        type=float,
        default=None,
        metavar="REV",
        help="travel window: its total width in revolutions, centred on the present position "
        "(the axis stays within +- half of it; required to tune)",
    )
    p.add_argument(
        "--torque-limit",
        type=float,
        default=100.0,
        metavar="PCT",
        help="torque limit during the run, %% of rated (default 100)",
    )
    p.add_argument(
        "--move-torque",
        type=float,
        default=None,
        metavar="PCT",
        help="servodesk's own tuning: the peak torque of the machine's own moves, %% of rated; "
        "the gains are ranked for a move accelerating at 70 %% of it (default: the torque limit)",
    )
    p.add_argument("--enable", action="store_true", help="servo on before tuning, off after")
    p.add_argument(
        "--store",
        action="store_true",
        help="store the parameters to non-volatile memory after a successful run",
    )
    p.add_argument(
        "--undo",
        choices=["before", "defaults"],
        default=None,
        help="only return the gains to before the last run or to the defaults",
    )
    _bus_options(p)
    p.set_defaults(func=run_tune)


def _check_args(args: argparse.Namespace) -> None:
    if args.undo is not None:
        if args.travel is not None:
            raise ValidationError(
                "--undo returns the gains only; it takes no --travel", field="undo"
            )
        return
    if args.travel is None:
        raise ValidationError(
            "--travel REV is required: the axis moves inside this window while it tunes",
            field="travel",
            hint="e.g. --travel 0.5 (+-0.25 rev around the present position)",
        )
    # The service's own bounds, checked here so that a bad argument exits 2 before the bus
    # is opened.
    from servodesk.services.tuning.capabilities import (
        MAX_MOVE_TORQUE_PCT,
        MAX_TORQUE_PCT,
        MAX_TRAVEL_REV,
    )

    if not 0 < args.travel <= MAX_TRAVEL_REV:
        raise ValidationError(
            f"--travel {args.travel:g} is outside 0 .. {MAX_TRAVEL_REV:g} revolutions",
            field="travel",
        )
    if not 0 < args.torque_limit <= MAX_TORQUE_PCT:
        raise ValidationError(
            f"--torque-limit {args.torque_limit:g} is outside 0 .. {MAX_TORQUE_PCT:g} %",
            field="torque_limit",
        )
    mt = args.move_torque
    if mt is not None and not (0 < mt <= MAX_MOVE_TORQUE_PCT and math.isfinite(mt)):
        raise ValidationError(
            f"--move-torque {mt:g} is outside 0 .. {MAX_MOVE_TORQUE_PCT:g} % of the rated torque",
            field="move_torque",
            hint="the peak torque your machine's moves use, e.g. 300",
        )


def run_tune(args: argparse.Namespace) -> int:
    _check_args(args)
    out = _run(args, lambda ctx: _tune(ctx, args))
    if args.json:
        _dump(out)
    else:
        _print(out)
    return 0 if out.get("ok") else 1


async def _tune(ctx: _Context, args: argparse.Namespace) -> dict[str, Any]:
    from servodesk.services.control import ControlService
    from servodesk.services.motion import MotionService
    from servodesk.services.tuning.jobs import TuningService
    from servodesk.settings import Settings

    session = await ctx.session()
    sid = session.id
    who = client_id()
    control = ControlService(ctx.hub)
    motion = MotionService(ctx.manager, control, ctx.hub, deadman_s=Settings().deadman_ms / 1000.0)
    service = TuningService(ctx.manager, motion, ctx.hub)
    token: str | None = None
    try:
        if args.undo is not None:
            undo = await service.undo(sid, who, args.undo)
            return {"ok": True, "session": sid, "undo": undo}
        # The CLI is its own holder and its own dead-man connection (services/control).
        token = control.take(sid, who)
        connection = control.connect(who)
        control.bind(connection, sid, token)
        if args.enable:
            await session.command("enable")
        beats = asyncio.get_running_loop().create_task(_heartbeats(control, connection, sid))
        try:
            job = await service.start(
                sid,
                who,
                mode=args.mode,
                travel_window_rev=args.travel,
                torque_limit_pct=args.torque_limit,
                move_torque_pct=args.move_torque,
            )
            if not args.json and job.get("bound"):
                print(f"travel window: {job['bound']['text']}", file=sys.stderr)
            job = await _follow(service, sid, quiet=args.json)
        except asyncio.CancelledError:
            # Ctrl-C: stop the tuning and the motion, put the gains back, then leave.
            task = asyncio.current_task()
            while task is not None and task.cancelling():
                task.uncancel()
            print("\nservodesk: stopping the tuning (Ctrl-C)...", file=sys.stderr)
            with contextlib.suppress(Exception):
                await service.stop(sid, who)
            raise
        finally:
            beats.cancel()
        result = service.result(sid)
        ok = job["state"] == "done"
        stored = None
        if ok and args.store:
            stored = await service.store(sid, who)
            result = service.result(sid)
        return {"ok": ok, "session": sid, "job": job, "result": result, "store": stored}
    finally:
        if args.enable and args.undo is None:
            with contextlib.suppress(Exception):
                await session.command("disable")
        with contextlib.suppress(Exception):
            control.release(sid, token)
        control.close()
        await motion.shutdown()


async def _heartbeats(control: Any, connection: str, sid: str) -> None:
    while True:
        control.heartbeat(connection, sid)
        await asyncio.sleep(HEARTBEAT_S)


async def _follow(service: Any, sid: str, *, quiet: bool) -> dict[str, Any]:
    """Wait for the job's end, printing its steps (stderr) unless ``quiet``."""
    last = ""
    while True:
        job: dict[str, Any] | None = service.job(sid)
        if job is None:
            raise ValidationError(f"no tuning job on {sid}")
        line = f"{round(job['progress'] * 100):3d} %  {job['step']}"
        if not quiet and line != last:
            print(line, file=sys.stderr)
            last = line
        if job["state"] != "running":
            return job
        await asyncio.sleep(0.1)


def _print(out: dict[str, Any]) -> None:
    if "undo" in out:
        u = out["undo"]
        print(u["note"])
        _print_gains([{**g, "after": g["value"], "raw_after": g["raw"]} for g in u["gains"]])
        return
    job, res = out["job"], out["result"]
    print(f"tuning {job['state']}: {job['message']}")
    err = res.get("error")
    if err:
        code = f"{err['code_hex']} " if err.get("code_hex") else ""
        print(f"  {code}{err['name']}")
        if err.get("cause"):
            print(f"  cause: {err['cause']}")
        if err.get("remedy"):
            print(f"  remedy: {err['remedy']}")
    _print_gains(res.get("gains") or [])
    for which in ("before", "after"):
        st = (res.get("step") or {}).get(which)
        if st:
            m = st["metrics"]
            print(
                f"step {which:<6} settling {_fmt(m.get('settling_s'), 's')}, overshoot "
                f"{_fmt(None if m.get('overshoot') is None else m['overshoot'] * 100, '%')}, "
                f"following error rms {_fmt(m.get('following_error_rms'), st['unit'])} "
                f"({st['source']})"
            )
    for note in res.get("notes") or []:
        print(f"note: {note}")
    if out.get("store"):
        print(f"stored: {out['store']['procedure']}")
    elif out.get("ok"):
        print("not stored (use --store, or the Parameters page, to keep the new gains)")


def _print_gains(gains: list[dict[str, Any]]) -> None:
    for g in gains:
        unit = g.get("unit") or ""
        before = g.get("before")
        line = f"  {g['label']:<36} "
        if before is not None or "raw_before" in g:
            line += f"{_fmt(before, unit)} -> "
        line += f"{_fmt(g.get('after'), unit)}"
        raw = f"raw {g.get('raw_before')} -> {g.get('raw_after')}" if "raw_before" in g else ""
        print(f"{line}  [{g['object']}{', ' + raw if raw else ''}]")


def _fmt(v: Any, unit: str) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g} {unit}".strip()
    return f"{v} {unit}".strip()
