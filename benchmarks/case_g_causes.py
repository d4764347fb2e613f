"""The paper's case (g) question: which named causes, at sizes a real rig can have, make the
model chaotic at beta = 0.022 and 10 Hz, as the paper's experiment was (its simulation,
and this project's baseline model, are period-2 there: docs/findings.md).

    python benchmarks/case_g_causes.py --work DIR [--figures docs/figures] [--json FILE]

1. For every cause of the registry (``analysis.extensions``) that acts on the dynamics, a
   regime map of case (g) with ``impact-rig map regimes`` (run here, one after another,
   each a command a reader can rerun; they are printed): the cause's parameter over its
   plausible range (21 values) against beta 0.012 to 0.032 (11 values, 0.022 among
   them), 2 random initial states per point, 400 drive periods settled and 100 kept.
   ``excitation_distortion`` is mapped over its size h2 and its phase phi2 at beta =
   0.022 (the phase has no plausible range: every phase).  ``contact_exponent`` changes the
   law's units with n, so its stiffness K_n follows n (``K_n = K delta_ref^(1.5 - n)``:
   the same force as the baseline's Hertz law at ``delta_ref``, the largest penetration
   of the baseline's period-2 orbit); one map per n (9 values over the plausible range)
   against beta.  The sensor causes change what is read, not the motion: a periodic
   motion read through a fixed map of the angle (zero, cubic, first-order lag) stays
   periodic, so none of them can make the record chaotic, and they are not mapped.
2. One figure, a panel per cause (``case_g_causes.png`` in ``--figures``), and the
   numbers (``--json``): for each cause, the sizes at beta = 0.022 at which a point's
   dominant attractor is chaotic, and at which any of its initial states found chaos.

3. ``impact-rig suggest`` on a report (written to ``--work``) that leaves the causes
   chaotic at case (g) indistinct, each at the smallest such size with an interval of one
   map step either side; its printout and plan (``case_g_next.toml`` in ``--work``).

Each map is kept in ``--work`` and a finished one is not run again (the map files
continue where they stopped).  The maps took about 8 minutes and the search 7 on 2 cores
under a load of 12 to 18.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import quantities as q
from analysis.dynamics.regime import KINDS
from analysis.extensions import CAUSES
from analysis.maps.store import read_map
from analysis.model import Model, paper_case
from analysis.simulate import SimulationSettings, simulate_packed
from rig.cli import main as rig_main

CASE = paper_case("g")
BETA_G = CASE.nondimensional.beta  # 0.022
BETAS = "beta=0.012:0.032:11"  # 0.002 apart: 0.022 is the sixth
SIZES = 21
EXPONENTS = 9
PHASES = 13
DPI = 80
SETTINGS = ["--transient-periods", "400", "--record-periods", "100", "--ics", "2",
            "--workers", "1", "--quiet"]
CHAOTIC = KINDS.index("chaotic")
# a size range narrower than the plausible one: pivot friction mapped over its whole
# plausible range (Tc_N_m=0:0.05:21, the rest as here) gives case (g)'s small pendulum
# (m g L = 0.0148 N m) a period-1 motion at every beta from 0.01 N m on; this resolves the
# sizes below
RANGES = {"coulomb_friction": (0.0, 0.01)}


def case_options() -> list[str]:
    """Case (g)'s drive frequency and nondimensional groups as map options."""
    nd = CASE.nondimensional
    return ["--f-drive-hz", f"{CASE.frequency_hz:g}", "--param", f"eta={nd.eta:g}",
            "--param", f"mu={nd.mu:g}", "--param", f"gamma={nd.gamma:g}"]


def largest_penetration_m() -> float:
    """The largest penetration of the baseline's settled orbit at case (g) (m)."""
    rig, drive = CASE.dimensional()
    model = Model(rig, drive)
    result = simulate_packed(model.pack(), -0.1, 0.0, settings=SimulationSettings(
        duration_s=4.0, fs_hz=50_000.0, skip_s=40.0, poincare_phase=None))
    delta = rig.l_m * (np.sin(result.theta) - math.sin(rig.theta_b_rad))
    return float(delta.max())


def maps(work: Path) -> list[dict[str, Any]]:
    """Every map's command (words after ``impact-rig``), file and what it shows."""
    out = []
    for name, cause in CAUSES.items():
        if cause.acts_on != "dynamics" or name == "contact_exponent":
            continue
        spec = cause.parameters[0]
        low, high = RANGES.get(name) or spec.plausible or (spec.lower, spec.upper)
        second = ["--vary", BETAS]
        if name == "excitation_distortion":
            second = ["--beta", f"{BETA_G:g}", "--vary", f"{q.phi2_rad}=-3.14159:3.14159:{PHASES}"]
        path = work / f"{name}.h5"
        out.append({"cause": name, "parameter": spec.name, "file": path,
                    "words": ["map", "regimes", *case_options(),
                              "--vary", f"{spec.name}={low:g}:{high:g}:{SIZES}", *second,
                              *SETTINGS, "--out", str(path)]})
    rig, _ = CASE.dimensional()
    delta = largest_penetration_m()
    low, high = CAUSES["contact_exponent"].parameters[0].plausible
    for n in np.linspace(low, high, EXPONENTS):
        k_n = rig.K_N_per_m1_5 * delta ** (1.5 - n)
        path = work / f"contact_exponent_n{n:.4f}.h5"
        out.append({"cause": "contact_exponent", "parameter": q.n, "file": path,
                    "delta_ref_m": delta, "K_n": k_n, "n": float(n),
                    "words": ["map", "regimes", *case_options(), "--vary", f"n={n:.4f}:{n:.4f}:1",
                              "--vary", BETAS, "--param", f"K_n={k_n:.6g}", *SETTINGS,
                              "--out", str(path)]})
    return out


def run(entry: dict[str, Any]) -> dict[str, Any]:
    """Run a map unless its file is finished; its points (size, second axis, regimes)."""
    path = entry["file"]
    done = path.exists() and read_map(path)["complete"]
    if not done:
        status = rig_main(entry["words"])
        if status != 0:
            raise SystemExit(f"impact-rig {' '.join(entry['words'])}: exit status {status}")
    data = read_map(path)
    summary, points = data["summary"], data["points"]
    regime = summary["regime"].reshape(-1, data["settings"]["ics"])
    return {"size": points[entry["parameter"]],
            "second": points[q.phi2_rad] if q.phi2_rad in points else points["beta"],
            "dominant": summary["point_regime"], "period": summary["point_period"],
            "any_chaotic": (regime == CHAOTIC).any(axis=1),
            "command": "impact-rig " + " ".join(entry["words"])}


def at_case_g(name: str, parameter: str, found: dict[str, np.ndarray]) -> dict[str, Any]:
    """The sizes at which case (g) is chaotic (beta = 0.022; every phase for h2)."""
    at = np.ones(found["size"].size, bool) if name == "excitation_distortion" \
        else np.isclose(found["second"], BETA_G)
    sizes = np.round(found["size"][at], 9)
    dominant = np.unique(sizes[found["dominant"][at] == CHAOTIC])
    anywhere = np.unique(sizes[found["any_chaotic"][at]])
    every = np.unique(sizes)
    return {"parameter": parameter, "sizes": every.tolist(),
            "chaotic_dominant": dominant.tolist(), "chaotic_any": anywhere.tolist(),
            "share_chaotic_dominant": float(np.mean(found["dominant"][at] == CHAOTIC)),
            "share_chaotic_any": float(np.mean(found["any_chaotic"][at]))}


def draw(results: dict[str, dict[str, np.ndarray]], path: Path) -> None:
    """One panel per cause: its size (x) against beta or phi2 (y), chaotic points red,
    periodic ones by period, others grey."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    names = list(results)
    columns = 4
    rows = math.ceil(len(names) / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(3.2 * columns, 2.8 * rows),
                                squeeze=False, constrained_layout=True)
    # 0 period-1, 1 period-2, 2 other period, 3 quasi-periodic, 4 chaotic, 5 none/other
    colours = ListedColormap(["#9ecae1", "#3182bd", "#74c476", "#fdae6b", "#d62728", "#bdbdbd"])
    for ax, name in zip(axes.flat, names, strict=False):
        found = results[name]
        code = np.full(found["size"].size, 5)
        code[(found["dominant"] == 0) & (found["period"] == 1)] = 0
        code[(found["dominant"] == 0) & (found["period"] == 2)] = 1
        code[(found["dominant"] == 0) & (found["period"] > 2)] = 2
        code[found["dominant"] == KINDS.index("quasi_periodic")] = 3
        code[found["dominant"] == CHAOTIC] = 4
        xs, ys = np.unique(found["size"]), np.unique(found["second"])
        grid = np.full((ys.size, xs.size), 5)
        for x, y, c in zip(found["size"], found["second"], code, strict=True):
            grid[np.searchsorted(ys, y), np.searchsorted(xs, x)] = c
        dx = (xs[-1] - xs[0]) / max(xs.size - 1, 1) / 2
        dy = (ys[-1] - ys[0]) / max(ys.size - 1, 1) / 2
        ax.imshow(grid, origin="lower", aspect="auto", interpolation="nearest", cmap=colours,
                  vmin=-0.5, vmax=5.5, extent=(xs[0] - dx, xs[-1] + dx, ys[0] - dy, ys[-1] + dy))
        phase = name == "excitation_distortion"
        if not phase:
            ax.axhline(BETA_G, color="black", lw=0.8, ls="--")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel(found["label"], fontsize=8)
        ax.set_ylabel("phi2_rad (beta 0.022)" if phase else "beta", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    handles = [plt.Rectangle((0, 0), 1, 1, color=colours(i)) for i in range(6)]
    figure.legend(handles, ["period-1", "period-2", "other period", "quasi-periodic",
                            "chaotic", "left the model / none"], loc="outside lower center",
                  ncol=6, fontsize=8)
    figure.suptitle("Case (g), 10 Hz: dominant attractor per cause over its plausible size "
                    "(dashed: beta = 0.022)", fontsize=10)
    figure.savefig(path, dpi=DPI)
    plt.close(figure)


def candidate_entry(name: str, at: dict[str, Any], found: dict[str, np.ndarray],
                    extra: dict[str, float]) -> dict[str, Any]:
    """A ranking entry (``impact-rig analyze --json``'s) for the cause at the smallest
    plausible size that makes case (g) chaotic, with an interval of one map step either
    side (the map's resolution; no record has measured it)."""
    rig, _ = CASE.dimensional()
    sizes = np.asarray(at["sizes"])
    step = float(np.min(np.diff(sizes))) if sizes.size > 1 else 0.0
    spec = CAUSES[name].parameters[0]
    low, high = spec.plausible or (spec.lower, spec.upper)
    chaotic = min(at["chaotic_dominant"], key=abs)
    parameters = {**baseline_parameters(rig),
                  spec.name: {"value": chaotic,
                              "ci95": [max(low, chaotic - step), min(high, chaotic + step)]}}
    for key, value in extra.items():
        parameters[key] = {"value": value, "held": True}
    if name == "excitation_distortion":  # the phase at that size where it was chaotic
        at_size = np.isclose(found["size"], chaotic) & (found["dominant"] == CHAOTIC)
        parameters[q.phi2_rad] = {"value": float(found["second"][at_size][0]), "held": True}
    return {"cause": name, "score": 0.0, "implausible": None,
            "model": {"causes": [name], "parameters": parameters}}


def baseline_parameters(rig: Any) -> dict[str, dict[str, Any]]:
    """Case (g)'s rig as a report's fitted parameters (held: the paper's values)."""
    return {q.omega_rad_s: {"value": math.sqrt(rig.g_m_s2 / rig.L_m), "held": True},
            q.zeta: {"value": rig.zeta, "held": True},
            q.K_N_per_m1_5: {"value": rig.K_N_per_m1_5, "held": True},
            q.mu0_s_per_m: {"value": rig.mu0_s_per_m, "held": True},
            q.theta_b_rad: {"value": rig.theta_b_rad, "held": True}}


def case_g_report(entries: list[dict[str, Any]], noise_rad: float) -> dict[str, Any]:
    """A forced record's report (the keys ``impact-rig suggest`` reads) that leaves the
    causes of ``entries`` indistinct at case (g): what an experiment at case (g) that was
    chaotic leaves open when each of them makes the model chaotic there."""
    rig, drive = CASE.dimensional()
    names = [e["cause"] for e in entries]
    return {
        "experiment": "forced", "made_by": "benchmarks/case_g_causes.py",
        "rig": rig.as_dict(), "sample_rate_hz": 1000.0, "noise_rad": noise_rad,
        "drive": {"frequency_hz": drive.frequency_hz,
                  "stated": {"frequency_hz": drive.frequency_hz,
                             "amplitude_m": drive.amplitude_m}},
        "cause": "none",
        "indistinct": [{"causes": [a, b], "why": "both make case (g) chaotic at a size a "
                        "real rig can have (benchmarks/case_g_causes.py's maps)"}
                       for i, a in enumerate(names) for b in names[i + 1:]],
        "ranking": entries,
        "baseline": {"parameters": baseline_parameters(rig)},
        "policy": {},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="folder of the map files")
    parser.add_argument("--figures", type=Path, help="write case_g_causes.png here")
    parser.add_argument("--json", type=Path, help="write the numbers here")
    parser.add_argument("--noise-rad", type=float, default=2e-4,
                        help="the angle noise suggest counts differences in (the shipped "
                        "rig file's noise_rad)")
    args = parser.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    results: dict[str, dict[str, Any]] = {}
    answer: dict[str, Any] = {}
    commands = []
    entries = maps(args.work)
    for entry in entries:
        print("impact-rig " + " ".join(entry["words"]), flush=True)
        found = run(entry)
        commands.append(found.pop("command"))
        name = entry["cause"]
        if name in results:  # contact_exponent: one map per n, joined
            results[name] = {k: np.concatenate([results[name][k], found[k]])
                             for k in found}
        else:
            results[name] = found
        results[name]["label"] = entry["parameter"] + (" (K_n follows n)" if name
                                                       == "contact_exponent" else "")
    for name, found in results.items():
        parameter = found["label"].split()[0]
        answer[name] = at_case_g(name, parameter, found)
        print(f"{name}: {parameter} chaotic at case (g) (dominant) at "
              f"{answer[name]['chaotic_dominant'] or 'no size'}; any initial state at "
              f"{answer[name]['chaotic_any'] or 'no size'}", flush=True)
    contact = [e for e in entries if e["cause"] == "contact_exponent"]
    survivors = []
    for name, at in answer.items():
        if not at["chaotic_dominant"]:
            continue
        extra = {}
        if name == "contact_exponent":  # the K_n of the map at that n
            n = min(at["chaotic_dominant"], key=abs)
            extra = {q.K_n: next(e["K_n"] for e in contact
                                 if np.isclose(e["n"], n, atol=1e-3))}
        survivors.append(candidate_entry(name, at, results[name], extra))
    suggestion = None
    if len(survivors) >= 2:
        report_path = args.work / "case_g.report.json"
        report_path.write_text(json.dumps(case_g_report(survivors, args.noise_rad), indent=2)
                               + "\n", encoding="utf-8")
        plan = args.work / "case_g_next.toml"
        words = ["suggest", str(report_path), "--best", "1", "--workers", "1",
                 "--out", str(plan), "--overwrite"]
        print("impact-rig " + " ".join(words), flush=True)
        status = rig_main(words)
        suggestion = {"command": "impact-rig " + " ".join(words), "status": status,
                      "candidates": [e["model"] for e in survivors],
                      "plan": plan.read_text(encoding="utf-8") if plan.exists() else None}
    if args.figures:
        args.figures.mkdir(parents=True, exist_ok=True)
        draw(results, args.figures / "case_g_causes.png")
    if args.json:
        args.json.write_text(json.dumps({
            "made_by": "benchmarks/case_g_causes.py", "commands": commands,
            "delta_ref_m": contact[0]["delta_ref_m"] if contact else None,
            "at_case_g": answer, "suggest": suggestion}, indent=2, default=float) + "\n",
            encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
