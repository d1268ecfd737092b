"""How the diagnosis does when a burner's ignition charge is documented.

Re-diagnoses the cases of a ``hil-client gap-benchmark`` run on an independent plant whose
background draws its burner's ignition charge (``draw_background(...)[KEY]``, kg as
received; the ninth plant's ``charge_kg``), each with its own charge given as
``--ignition-charge-kg`` would give it, and scores both against the sealed truth:

    .venv/bin/python bench/gap_charge.py OUT_DIR [--key charge_kg] [--workers 2]

The charge comes from the plant's own seed, not from the log: this measures what a lab
that knows its burner's start-up program gains, not what the diagnosis can infer.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from multiprocessing import Pool
from pathlib import Path

import numpy as np
import yaml

from hil_client.analysis.diagnose import diagnose
from hil_client.analysis.gap_benchmark import is_right
from hil_client.analysis.logio import read_log
from hil_client.analysis.phases import find_phases
from rig_emulator.model.params import params_from_mapping


def _rediagnose(job: tuple[Path, dict, str]) -> tuple[dict, float, str, bool | None]:
    out, truth, key = job
    case = out / "cases" / f"case_{truth['case']:02d}"
    boiler = yaml.safe_load((case / "boiler.yaml").read_text())
    plant = importlib.import_module(truth["plant"])
    charge_kg = float(plant.draw_background(np.random.default_rng(truth["seed"]), boiler)[key])
    cal, val = (read_log(case / f"{name}.csv") for name in truth["pair"])
    doc = params_from_mapping(boiler, str(case / "boiler.yaml"))
    content = diagnose(cal, find_phases(cal), val, find_phases(val), doc, charge_kg).content
    return truth, charge_kg, content["effect"], (content["shrinkage"] or {}).get("confirmed")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="output directory of gap-benchmark")
    parser.add_argument("--key", default="charge_kg", help="background key of the charge")
    parser.add_argument("--workers", type=int, default=2, help="parallel processes [2]")
    args = parser.parse_args(argv)
    try:
        truths = json.loads((args.out / "sealed" / "truth.json").read_text())
        before = {
            r["case"]: r for r in json.loads((args.out / "scores.json").read_text())["results"]
        }
        plant = importlib.import_module(truths[0]["plant"])
        boiler = yaml.safe_load((args.out / "cases" / "case_00" / "boiler.yaml").read_text())
        plant.draw_background(np.random.default_rng(0), boiler)[args.key]
    except (OSError, ValueError, KeyError, IndexError, AttributeError, ImportError) as exc:
        print(f"gap_charge: {args.out}: not a benchmark of a plant with a background "
              f"'{args.key}' ({type(exc).__name__}: {exc})", file=sys.stderr)  # fmt: skip
        return 2
    jobs = [(args.out, t, args.key) for t in truths]
    if args.workers <= 1:
        results = [_rediagnose(job) for job in jobs]
    else:
        with Pool(args.workers) as pool:
            results = pool.map(_rediagnose, jobs)
    right_before = right_after = 0
    for truth, charge_kg, found, confirmed in results:
        old = before[truth["case"]]
        right_before += is_right(truth["effect"], old)
        right_after += is_right(truth["effect"], {"found": found, "confirmed": confirmed})
        if found != old["found"]:
            print(f"case {truth['case']:2d} truth {truth['effect']:20s} charge {charge_kg:.3f} kg: "
                  f"{old['found']} -> {found}")  # fmt: skip
    n = len(results)
    print(f"right: {right_before} of {n} without the charge, {right_after} of {n} with it")
    return 0


if __name__ == "__main__":
    sys.exit(main())
