"""Would other mark floors have named better on a plant they were not chosen on?

Reads the output directories of ``hil-client gap-benchmark`` (``diagnosis.json`` of every
case and ``sealed/truth.json``), re-decides every case with each candidate's mark floor
scaled by a factor (a candidate is named when its held-out evidence names it and its mark
reaches the scaled floor; of several, the ranking of :func:`diagnose._answer`), and, leaving
one plant out at a time, picks the factors that score best on the other plants and scores
them on the one left out. If the left-out accuracy does not beat the current floors', the
floors are not what limits the diagnosis on plants it was not written beside.

    .venv/bin/python bench/gap_floors.py OUT_DIR [OUT_DIR ...]

Check first: with every factor 1 the re-decision must give every case the answer the
diagnosis gave (printed; a mismatch means ``diagnosis.json`` does not carry what the
decision used).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hil_client.analysis.augment import EFFECTS
from hil_client.analysis.diagnose import _answer

#: Factors on each candidate's floor (1: as the diagnosis has it); the pre-feed's floor
#: (40 s of feed) is spread wider, since the plants' normal starts read 0-259 s.
FACTORS = {
    "body_heat_diffusion": (0.75, 1.0, 1.25, 1.5, 2.0, 3.0),
    "outlet_sensor_pipe": (0.75, 1.0, 1.25, 1.5, 2.0, 3.0),
    "ignition_delay": (0.5, 1.0, 2.0, 3.0, 4.0, 6.0),
    "flue_gas_lag": (0.75, 1.0, 1.25, 1.5, 2.0, 3.0),
    "fuel_energy_bias": (0.75, 1.0, 1.25, 1.5, 2.0),
}


def read_cases(dirs: list[Path]) -> list[dict]:
    """One record per diagnosed case: plant, truth, answer, and per candidate its evidence
    verdict, its margin (mark over floor) and whether it shrank the held-out gap."""
    cases = []
    for d in dirs:
        for truth in json.loads((d / "sealed" / "truth.json").read_text()):
            path = d / "cases" / f"case_{truth['case']:02d}" / "diagnosis" / "diagnosis.json"
            if not path.exists():  # a case that ended in a one-line error
                continue
            diagnosis = json.loads(path.read_text())
            candidates = {}
            for c in diagnosis["candidates"]:
                before, after = c["validation_rmsd_before"], c["validation_rmsd_after"]
                candidates[c["effect"]] = {
                    "evidence": c["evidence_named"],
                    "margin": c["margin"] or 0.0,
                    "shrinks": before is not None and after is not None and before > after,
                }
            cases.append(
                {
                    "plant": truth["plant"].rsplit(".", 1)[-1],
                    "truth": truth["effect"],
                    "answer": diagnosis["effect"],
                    "candidates": candidates,
                }
            )
    return cases


def answer(case: dict, factors: dict[str, float]) -> str:
    """The diagnosis's answer with each candidate's floor scaled by ``factors``."""
    verdicts, scaled = {}, {}
    for effect, c in case["candidates"].items():
        margin = c["margin"] / factors[effect]
        verdicts[effect] = (c["evidence"] and margin >= 1.0, 0.0, "")
        scaled[effect] = SimpleNamespace(margin=margin)
    return _answer(verdicts, scaled)


def right(case: dict, found: str) -> bool:
    """As the benchmark scores: the truth, and for an effect a shrinking held-out gap."""
    if found != case["truth"]:
        return False
    return found == "none" or case["candidates"][found]["shrinks"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dirs", nargs="+", type=Path, help="gap-benchmark output directories")
    args = parser.parse_args(argv)
    missing = [d for d in args.dirs if not (d / "sealed" / "truth.json").is_file()]
    if missing:
        print(f"gap_floors: not a gap-benchmark output: {missing[0]}", file=sys.stderr)
        return 2
    cases = read_cases(args.dirs)
    combos = [dict(zip(EFFECTS, f, strict=True)) for f in itertools.product(*FACTORS.values())]
    current = combos.index(dict.fromkeys(EFFECTS, 1.0))
    same = sum(answer(c, combos[current]) == c["answer"] for c in cases)
    print(f"{len(cases)} cases; re-decided as diagnosed: {same} of {len(cases)}")
    plants = sorted({c["plant"] for c in cases})
    hits = np.array([[right(c, answer(c, f)) for f in combos] for c in cases])
    where = np.array([c["plant"] for c in cases])
    accuracy = {p: hits[where == p].mean(axis=0) for p in plants}
    print(f"{'left out':<10} {'current':>8} {'chosen':>8}  factors chosen on the others")
    # of factors that score alike, the ones nearest the floors as they are
    distance = np.array([sum(abs(np.log(v)) for v in f.values()) for f in combos])
    left_out = []
    for p in plants:
        others = [q for q in plants if q != p]
        if not others:
            break
        best = int(np.lexsort((distance, -np.mean([accuracy[q] for q in others], axis=0)))[0])
        left_out.append((accuracy[p][current], accuracy[p][best]))
        factors = " ".join(f"{e.split('_')[0]} {v:g}" for e, v in combos[best].items())
        print(f"{p:<10} {accuracy[p][current]:>8.0%} {accuracy[p][best]:>8.0%}  {factors}")
    if left_out:
        now, chosen = np.mean(left_out, axis=0)
        print(f"{'mean':<10} {now:>8.0%} {chosen:>8.0%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
