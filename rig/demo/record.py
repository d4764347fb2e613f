"""The demo's rig side: the report folder, the virtual rig with its hidden cause switched on,
its true values, and the three recordings (free decay, impact decay, forced sweep)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import MappingProxyType

from analysis import quantities as q
from analysis.progress import ProgressText
from rig.config import RigConfig
from rig.demo.settings import (
    ANALYSIS,
    FIGURES,
    NONE,
    RECORDINGS,
    DemoError,
    DemoSettings,
    HiddenCause,
    indented,
)
from rig.procedures import (
    RIG_FAILURES,
    DecayPlan,
    ProcedureResult,
    SweepPlan,
    record_decay,
    run_sweep,
)


def prepare_folder(folder: str | Path, *, overwrite: bool = False) -> Path:
    """Create the report folder; refuse a non-empty one unless ``overwrite``."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise DemoError(f"{folder}: exists and is not a folder")
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise DemoError(
            f"{folder}: folder is not empty; choose another --out or pass --overwrite "
            "(the demo's files in it are then replaced)"
        )
    try:
        for sub in ("", RECORDINGS, FIGURES, ANALYSIS):
            (folder / sub).mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise DemoError(f"{folder}: cannot create the report folder ({error})") from None
    return folder


def demo_config(config: RigConfig, hidden: HiddenCause) -> RigConfig:
    """The rig file run on the virtual rig, with exactly the hidden cause switched on."""
    causes = {} if hidden.name == NONE else {hidden.name: MappingProxyType(dict(hidden.values))}
    virtual = replace(config.virtual, causes=MappingProxyType(causes))
    return replace(config, kind="virtual", virtual=virtual)


def warm_up_physics(config: RigConfig) -> None:
    """Compile (or load from numba's cache) the virtual rig's physics before the devices stream:
    a first compilation takes tens of seconds, and a board that says nothing that long
    would be taken for a dead one."""
    from analysis.model import Drive, Model, RigParameters
    from analysis.simulate import SimulationSettings, simulate

    rig = RigParameters(L_m=config.constants.L_m)
    model = Model(rig=rig, drive=Drive(amplitude_m=1e-3, frequency_hz=10.0), barrier=True)
    settings = SimulationSettings(duration_s=0.5, fs_hz=1000.0)
    simulate(model, -0.1, settings=settings)
    simulate(replace(model, drive=Drive(), barrier=False), 0.1, settings=settings)


def true_values(config: RigConfig) -> dict[str, float]:
    """The virtual rig's true values under the docs/MODEL.md section 7 keys."""
    from analysis.model import RigParameters

    c = config.constants
    rig = RigParameters(m_kg=c.m_kg, l_m=c.l_m, L_m=c.L_m, R_m=c.R_m, g_m_s2=c.g_m_s2)
    return {
        q.L_m: rig.L_m,
        q.omega_rad_s: rig.omega_rad_s,
        q.zeta: rig.zeta,
        q.K_N_per_m1_5: rig.K_N_per_m1_5,
        q.E_Pa: rig.E_Pa,
        q.mu0_s_per_m: rig.mu0_s_per_m,
        q.theta_b_rad: config.virtual.theta_b_rad,
    }


def record_everything(
    config: RigConfig, folder: Path, settings: DemoSettings, say: ProgressText
) -> dict[str, ProcedureResult]:
    """The three recordings; a device or recording failure is a DemoError saying so."""
    try:
        return _record_on_open_rig(config, folder, settings, say)
    except RIG_FAILURES as error:
        raise DemoError(
            f"recording on the virtual rig failed: {error} (the drive was ramped to zero; the "
            f"recordings so far are in {folder / RECORDINGS})"
        ) from None


def _record_on_open_rig(
    config: RigConfig, folder: Path, settings: DemoSettings, say: ProgressText
) -> dict[str, ProcedureResult]:
    from rig.devices import open_rig

    speed = settings.virtual_speed
    wall = 1.0 / speed  # a decay's longest duration is wall-clock seconds
    L = config.constants.L_m
    out = folder / RECORDINGS
    devices = open_rig(config, sample_rate_hz=settings.sample_rate_hz, virtual_speed=speed)
    results = {}
    try:
        decays = (
            (
                "free_decay",
                settings.free_release_rad,
                "free decay (barrier out): hold, release, record until the swing dies down",
            ),
            ("impact_decay", settings.impact_release_rad, "impact decay (barrier in)"),
        )
        for experiment, release_rad, what in decays:
            say(f"  {what}")
            results[experiment] = record_decay(
                devices,
                out / f"{experiment}.h5",
                DecayPlan(
                    experiment,
                    release_angle_rad=release_rad,
                    stop_below_rad=settings.decay_stop_below_rad,
                    max_duration_s=settings.decay_max_s * wall,
                ),
                notes=f"impact-rig demo: {experiment.replace('_', ' ')}",
                overwrite=True,
                progress=indented(say),
            )
        devices.set_barrier(True)
        f = settings.sweep_frequency_hz
        say(
            f"  forced sweep at {f:g} Hz, beta {settings.sweep_betas[0]:g} .. "
            f"{settings.sweep_betas[-1]:g} and back (A = beta L)"
        )
        results["sweep"] = run_sweep(
            devices,
            out / f"sweep_{f:g}Hz.h5",
            SweepPlan(
                parameter="amplitude",
                values=tuple(beta * L for beta in settings.sweep_betas),
                fixed=f,
                settle_s=settings.settle_s,  # rig time: counted on the samples
                dwell_s=settings.dwell_s,
                down=True,
            ),
            notes=f"impact-rig demo: amplitude sweep at {f:g} Hz",
            overwrite=True,
            progress=indented(say),
        )
    finally:
        devices.close()
    for result in results.values():
        say(
            f"  {result.path.name}: {result.samples_written} samples, {result.samples_lost} lost "
            f"({result.stop_reason})"
        )
    return results
