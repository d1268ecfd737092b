"""``rig-emulator``: the pellet-boiler test-bench emulator.

Exit codes: 0 success, 2 bad usage or bad input (one line naming what is wrong), 1 any
other failure.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from rig_emulator.boilers import load_boiler
from rig_emulator.cli_support import Parser, UsageError, report
from rig_emulator.model import pack_constants, steady_state
from rig_emulator.model.params import ParameterError


def _build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="rig-emulator", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    check = sub.add_parser("check", help="validate a boiler parameter file and print it")
    check.add_argument("--boiler", required=True, help="boiler NAME or parameter file PATH")
    steady = sub.add_parser(
        "steady",
        help="closed-form steady state at a load (energy split of Eq. 1-10)",
        description="Print the steady operating point of the one-node model at a load.",
    )
    steady.add_argument("--boiler", required=True, help="boiler NAME or parameter file PATH")
    steady.add_argument("--load", type=float, default=100.0, help="load [%% of nominal] [100]")
    steady.add_argument("--return-temp", type=float, default=55.0, help="return [C] [55]")
    steady.add_argument("--room-temp", type=float, default=22.0, help="room [C] [22]")
    return parser


def _load(name: str):
    try:
        return load_boiler(name)
    except ParameterError as exc:
        raise UsageError(str(exc)) from None


def _cmd_check(args: argparse.Namespace) -> int:
    params = _load(args.boiler)
    for key, value in params.to_mapping().items():
        print(f"{key}: {value}")
    return 0


def _cmd_steady(args: argparse.Namespace) -> int:
    params = _load(args.boiler)
    if not 0.0 < args.load <= 150.0:
        raise UsageError(f"--load: {args.load} is outside 0..150 %")
    flow = args.load / 100.0 * params.nominal_flow_kg_h
    ss = steady_state(pack_constants(params), flow, args.return_temp, args.room_temp)
    share = 100.0 / ss.q_fuel_kW
    print(f"{params.name} at {args.load:g} % load ({flow:.1f} kg/h, return {args.return_temp} C)")
    print(f"  T_boiler   {ss.t_boiler_C:8.2f} C     T_flue_gas {ss.t_flue_gas_C:8.2f} C")
    print(f"  firing     {ss.firing_kW:8.3f} kW    fuel (dry) {ss.fuel_dry_kg_h:8.3f} kg/h")
    print(f"  Q_fuel     {ss.q_fuel_kW:8.3f} kW    100.0 %")
    print(f"  Q_water    {ss.q_water_kW:8.3f} kW    {ss.q_water_kW * share:5.1f} %")
    print(f"  Q_fluegas  {ss.q_flue_gas_kW:8.3f} kW    {ss.q_flue_gas_kW * share:5.1f} %")
    print(f"  Q_amb      {ss.q_amb_kW:8.3f} kW    {ss.q_amb_kW * share:5.1f} %")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``rig-emulator``; returns the exit code."""
    try:
        args = _build_parser().parse_args(argv)
        return {"check": _cmd_check, "steady": _cmd_steady}[args.command](args)
    except UsageError as exc:
        return report(exc, "rig-emulator")


if __name__ == "__main__":
    sys.exit(main())
