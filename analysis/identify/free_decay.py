"""Free decay without barrier: effective length L = g / omega^2, damping ratio zeta, initial angle.

Small swings are fitted with the averaging solution of docs/MODEL.md section 4 (a closed
form, fast); larger swings, where that solution's neglected terms exceed what the
data resolve, by simulating the full pendulum equation.  The switch is at
``AVERAGING_MAX_AMPLITUDE_RAD`` = 0.2 rad.  The averaging solution neglects
terms that grow with the swing: the amplitude dependence of the decay rate biases
zeta by about theta0^2 / 24 (0.2 % at 0.2 rad, measured 0.3 % at 0.25 rad), the
next-order frequency term (11/3072 theta0^4) biases L by 1e-5 and the third
harmonic (theta0^3/192) is 4e-5 rad; at 0.2 rad all of these stay inside the
intervals of a typical record, beyond it the zeta bias soon does not.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from analysis import quantities as q
from analysis.experiments import FREE_DECAY
from analysis.identify.intervals import Z95, Covariance, sandwich_covariance
from analysis.identify.preprocess import PreparedSignal, prepare
from analysis.identify.result import Estimate, FitQuality, IdentificationError, IdentificationResult
from analysis.identify.start_values import DecayGuess, guess_decay
from analysis.identify.threads import blas_on_one_thread
from analysis.records import Record

AVERAGING_MAX_AMPLITUDE_RAD = 0.2
OUTLIER_SIGMAS = 6.0  # residuals beyond this many robust standard deviations are excluded
MAX_OUTLIER_FRACTION = 0.01  # more "outliers" than this is model misfit, not bad samples
POOR_FIT_RATIO = 3.0  # residual rms this many times the noise: the model misses structure
ROBUST_PASS_SAMPLES = 6000
LSMR_ABOVE_RESIDUALS = 20_000
CONTINUATION_START_PERIODS = 4.0
# Relative finite-difference step for simulated curves: the simulator's output moves by
# ~1e-9 rad when a parameter moves by nothing, so the step must dwarf that.
SIMULATION_DIFF_STEP = 1e-5
CONTINUATION_GROWTH = 3.0
METHODS = ("auto", "averaging", "simulation")


def averaging_solution(
    t: np.ndarray, amplitude: float, phase: float, zeta: float, omega: float, offset: float = 0.0
) -> np.ndarray:
    """theta(t) of docs/MODEL.md section 4 plus a sensor offset (softening pendulum, small swings).

    The carrier runs at the damped frequency omega sqrt(1 - zeta^2): the averaging
    solution is first order in zeta, and the second-order shift (4e-4 relative at
    zeta = 0.03) would otherwise bias L by twice that.  The phase drift
    th0^2/(32 zeta) (exp(-2 zeta omega t) - 1) is evaluated as
    -th0^2 omega t / 16 * (1 - exp(-x)) / x with x = 2 zeta omega t, so zeta -> 0 is exact.
    """
    x = 2.0 * zeta * omega * t
    with np.errstate(invalid="ignore", divide="ignore"):
        shrink = np.where(x > 1e-8, -np.expm1(-x) / np.where(x > 1e-8, x, 1.0), 1.0 - 0.5 * x)
    drift = -(amplitude**2) * omega * t / 16.0 * shrink
    carrier = omega * math.sqrt(max(1.0 - zeta * zeta, 0.0)) * t
    return amplitude * np.exp(-zeta * omega * t) * np.cos(carrier + phase + drift) + offset


def simulated_free_decay(
    t: np.ndarray, theta0: float, theta_dot0: float, zeta: float, omega: float, g: float
) -> np.ndarray:
    """The full pendulum equation, no barrier nor drive, sampled at uniform ``t`` (t[0] = 0)."""
    from analysis.model import Drive, Model, RigParameters
    from analysis.simulate import SimulationSettings, simulate

    dt = float(t[1] - t[0])
    model = Model(
        rig=RigParameters(L_m=g / omega**2, zeta=zeta, g_m_s2=g), drive=Drive(), barrier=False
    )
    result = simulate(
        model, theta0, theta_dot0,
        settings=SimulationSettings(
            duration_s=t.size * dt, fs_hz=1.0 / dt, poincare_phase=None, rtol=1e-10, atol=1e-12,
        ),
    )
    theta = np.asarray(result.theta, dtype=float)[: t.size]
    if theta.size < t.size:
        # The trial state left the experiment's regime (e.g. over the top): hold the last
        # angle so the optimiser sees a large residual and steps back, instead of failing.
        last = theta[-1] if theta.size else theta0
        theta = np.concatenate([theta, np.full(t.size - theta.size, last)])
    return theta


def fit_free_decay(
    record: Record, *, method: str = "auto", detect_release: bool = True
) -> IdentificationResult:
    """Identify L, omega, zeta, initial angle and sensor offset from one free-decay record."""
    blas_on_one_thread()
    if method not in METHODS:
        raise ValueError(f"method {method!r}; expected one of {METHODS}")
    signal = prepare(record.time_s, record.angle_rad, detect_release=detect_release)
    guess = guess_decay(signal)
    if method == "auto":
        method = "averaging" if guess.amplitude_rad <= AVERAGING_MAX_AMPLITUDE_RAD else "simulation"
    g = record.gravity_m_s2
    if method == "averaging":
        names = ("amplitude_rad", "phase_rad", q.zeta, q.omega_rad_s, q.offset_rad)
        x0 = [guess.amplitude_rad, guess.phase_rad, guess.zeta, guess.omega_rad_s,
              guess.offset_rad]
        lower = [0.0, guess.phase_rad - math.pi, 0.0, 0.5 * guess.omega_rad_s, -math.inf]
        upper = [math.inf, guess.phase_rad + math.pi, 1.0, 2.0 * guess.omega_rad_s, math.inf]

        def curve(t: np.ndarray, x: np.ndarray) -> np.ndarray:
            return averaging_solution(t, *x)
    else:
        theta0_guess, theta_dot0_guess = _initial_state(signal, guess)
        # The small-angle guess underestimates omega for large swings; widen the bounds.
        # The period from the turning points belongs to their median swing.
        typical = float(np.median(guess.turning_amplitudes_rad))
        omega_small = guess.omega_rad_s * _period_factor(typical)
        names = (q.theta0_rad, q.theta_dot0_rad_s, q.zeta, q.omega_rad_s, q.offset_rad)
        x0 = [theta0_guess, theta_dot0_guess, guess.zeta, omega_small, guess.offset_rad]
        lower = [-math.pi, -math.inf, 0.0, 0.5 * omega_small, -math.inf]
        upper = [math.pi, math.inf, 1.0, 2.0 * omega_small, math.inf]

        def curve(t: np.ndarray, x: np.ndarray) -> np.ndarray:
            return simulated_free_decay(t, x[0], x[1], x[2], x[3], g) + x[4]

    x, cov, quality, excluded = _robust_fit(
        signal, curve, x0, lower, upper, 2.0 * math.pi / guess.omega_rad_s,
        diff_step=None if method == "averaging" else SIMULATION_DIFF_STEP,
    )
    values = dict(zip(names, x, strict=True))
    omega, zeta = values[q.omega_rad_s], values[q.zeta]
    i_omega, i_zeta = names.index(q.omega_rad_s), names.index(q.zeta)
    parameters: dict[str, Estimate] = {}
    grad = np.zeros(len(names))
    grad[i_omega] = -2.0 * g / omega**3
    L = g / omega**2
    parameters[q.L_m] = Estimate(L, cov.derived_ci95(L, grad))
    parameters[q.omega_rad_s] = Estimate(omega, cov.ci95(omega, i_omega))
    parameters[q.zeta] = Estimate(zeta, cov.ci95(zeta, i_zeta))
    if method == "averaging":
        amplitude, phase = values["amplitude_rad"], values["phase_rad"]
        theta0 = amplitude * math.cos(phase)
        grad = np.zeros(len(names))
        grad[0], grad[1] = math.cos(phase), -amplitude * math.sin(phase)
        parameters[q.theta0_rad] = Estimate(theta0, cov.derived_ci95(theta0, grad))
    else:
        parameters[q.theta0_rad] = Estimate(values[q.theta0_rad], cov.ci95(values[q.theta0_rad], 0))
    i_off = names.index(q.offset_rad)
    parameters[q.offset_rad] = Estimate(values[q.offset_rad], cov.ci95(values[q.offset_rad], i_off))
    warnings = list(_fit_warnings(signal, guess, quality))
    details = {
        "fit_model": "averaging solution" if method == "averaging" else "full simulation",
        q.g_m_s2: g,
        "release_trim_s": signal.trim_start_s,
        "rest_trim_s": signal.trim_end_s,
        "nonfinite_samples": signal.n_nonfinite,
        "spike_samples": signal.n_spikes,
        "outlier_samples": excluded,
        "initial_amplitude_rad": float(guess.amplitude_rad),
        "interval_method": "Newey-West sandwich (Bartlett), bandwidth from residual "
        "autocorrelation, never narrower than the white-noise interval",
        "fitted": {k: float(v) for k, v in values.items()},
        "damping_by_amplitude": _damping_by_amplitude(guess),
        "preprocessing": list(signal.notes),
    }
    return IdentificationResult(
        experiment=record.experiment,
        method=f"free decay, {details['fit_model']}",
        parameters=parameters,
        quality=quality,
        warnings=tuple(warnings),
        details=details,
    )


def _period_factor(amplitude: float) -> float:
    """Large-swing period over small-swing period, T/T0 = pi / (2 K(sin^2(a/2)))."""
    from scipy.special import ellipk

    a = min(abs(amplitude), 3.0)
    return float(2.0 * ellipk(math.sin(a / 2.0) ** 2) / math.pi)


def _initial_state(signal: PreparedSignal, guess: DecayGuess) -> tuple[float, float]:
    """Angle and angular velocity at t = 0 from a quadratic fit to the first samples."""
    t = signal.time_s
    n = max(5, int(0.05 * 2 * math.pi / guess.omega_rad_s / max(t[1] - t[0], 1e-12)))
    head = np.flatnonzero(signal.valid[:n])
    if head.size < 3:
        return float(signal.angle_rad[signal.valid][0] - guess.offset_rad), 0.0
    coeffs = np.polyfit(t[head], signal.angle_rad[head] - guess.offset_rad, 2)
    return float(coeffs[2]), float(coeffs[1])


def _robust_fit(
    signal: PreparedSignal,
    curve: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x0: Sequence[float],
    lower: Sequence[float],
    upper: Sequence[float],
    period_s: float,
    diff_step: float | None = None,
) -> tuple[np.ndarray, Covariance, FitQuality, int]:
    """Robust (soft L1) fit, exclusion of isolated outliers, final least squares and intervals.

    ``diff_step`` is the relative finite-difference step; a simulated curve needs one
    well above the integrator's tolerance, or the Jacobian is integration noise.
    """
    t = signal.time_s
    use = signal.valid.copy()
    data = signal.angle_rad
    x0 = np.clip(np.asarray(x0, dtype=float), lower, upper)

    def residual(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
        # Simulate only as far as the samples in use (the early windows are short).
        stop = int(np.flatnonzero(mask)[-1]) + 1
        return (curve(t[:stop], x) - data[:stop])[mask[:stop]]

    # The robust pass only has to find the basin and the outliers: a thinned record
    # (every k-th sample) does that at a fraction of the cost of the full one.
    thin = use.copy()
    stride = max(1, t.size // ROBUST_PASS_SAMPLES)
    if stride > 1:
        keep = np.zeros(t.size, dtype=bool)
        keep[::stride] = True
        thin &= keep
    # Plain least squares first, so that the robust loss is scaled to the residuals the
    # model really leaves (on real data far above the sensor noise) and not to the noise.
    # On a long record the cost is a comb in omega; fitting a few periods first and
    # then ever longer spans keeps each step inside the basin of the true minimum.
    x_start = x0
    span = CONTINUATION_START_PERIODS * period_s
    while span < t[-1]:
        window = thin & (t <= span)
        x_start = least_squares(
            residual, x_start, bounds=(lower, upper), method="trf", x_scale="jac",
            diff_step=diff_step, args=(window,), max_nfev=100,
        ).x
        span *= CONTINUATION_GROWTH
    plain = least_squares(
        residual, x_start, bounds=(lower, upper), method="trf", x_scale="jac",
        diff_step=diff_step, args=(thin,),
    )
    r = plain.fun
    spread = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    robust = least_squares(
        residual, plain.x, bounds=(lower, upper), method="trf", loss="soft_l1", diff_step=diff_step,
        f_scale=3.0 * max(spread, signal.noise_rad), x_scale="jac", args=(thin,),
        max_nfev=200,
    )
    r = residual(robust.x, use)
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    far = np.abs(r) > OUTLIER_SIGMAS * max(sigma, signal.noise_rad)
    excluded = 0
    if 0 < np.count_nonzero(far) <= MAX_OUTLIER_FRACTION * r.size:
        idx = np.flatnonzero(use)
        use[idx[far]] = False
        excluded = int(np.count_nonzero(far))
    final = least_squares(
        residual, robust.x, bounds=(lower, upper), method="trf", x_scale="jac",
        diff_step=diff_step, args=(use,), tr_solver=_trust_region_solver(np.count_nonzero(use)),
    )
    if not final.success:
        raise IdentificationError(f"the fit did not converge: {final.message}")
    r = final.fun
    cov = sandwich_covariance([(r, final.jac)])
    quality = FitQuality(
        rms_residual_rad=float(np.sqrt(np.mean(r**2))),
        noise_rad=signal.noise_rad,
        n_samples=int(r.size),
        n_excluded=signal.n_excluded + excluded,
        variance_inflation=cov.variance_inflation,
        residual_lag1_correlation=cov.lag1_correlation,
    )
    return final.x, cov, quality, excluded


def _trust_region_solver(n_residuals: int) -> str:
    """'exact' (an SVD per step) for small problems, 'lsmr' for long records.

    The SVD of a 100 000 x 8 Jacobian runs in threaded BLAS, which on a busy 2-core
    machine stalls for 0.2-0.6 s a step (measured); LSMR needs only matrix-vector
    products, a few milliseconds.
    """
    return "lsmr" if n_residuals > LSMR_ABOVE_RESIDUALS else "exact"


def _damping_by_amplitude(guess: DecayGuess) -> dict[str, float]:
    """Log decrement per unit time early and late in the record: equal for viscous damping."""
    amps, times = guess.turning_amplitudes_rad, guess.turning_times_s
    keep = amps > 0
    amps, times = amps[keep], times[keep]
    if amps.size < 6:
        return {}
    third = amps.size // 3
    rates = []
    for sl in (slice(0, third + 1), slice(amps.size - third - 1, amps.size)):
        slope = np.polyfit(times[sl], np.log(amps[sl]), 1)[0]
        rates.append(float(-slope / guess.omega_rad_s))
    return {"zeta_large_amplitude": rates[0], "zeta_small_amplitude": rates[1]}


def _fit_warnings(signal: PreparedSignal, guess: DecayGuess, quality: FitQuality):
    if signal.trim_start_s > 0:
        yield f"record trimmed by {signal.trim_start_s:.4g} s at the start (before release)"
    if signal.n_nonfinite or signal.n_spikes:
        yield (
            f"excluded {signal.n_nonfinite} non-finite and {signal.n_spikes} spike sample(s)"
        )
    ratio = quality.rms_residual_rad / max(quality.noise_rad, 1e-300)
    if ratio > POOR_FIT_RATIO:
        yield (
            f"poor fit: residual rms {quality.rms_residual_rad:.3g} rad is {ratio:.3g} x the "
            "sample noise; the model leaves structure unexplained (see damping_by_amplitude)"
        )
    rates = _damping_by_amplitude(guess)
    if rates:
        big, small = rates["zeta_large_amplitude"], rates["zeta_small_amplitude"]
        if min(big, small) > 0 and max(big, small) / min(big, small) > 1.5:
            kind = (
                "rises as the swing decays (Coulomb-like friction)" if small > big
                else "falls as the swing decays (drag-like)"
            )
            yield (
                f"damping depends on amplitude: apparent zeta {big:.3g} at large swings, "
                f"{small:.3g} at small; it {kind} - viscous zeta is an average"
            )
    if quality.variance_inflation > 10.0:
        yield (
            f"residuals are strongly correlated: intervals widened x"
            f"{math.sqrt(quality.variance_inflation):.3g} over the white-noise formula"
        )


def pool_free_decays(results: Sequence[IdentificationResult]) -> IdentificationResult:
    """Inverse-variance pooling of omega and zeta from separate free-decay fits of one pendulum.

    Each record keeps its own initial angle and offset; the pooled interval is widened
    by the Birge ratio sqrt(chi^2 / (k - 1)) when the records disagree beyond their intervals.
    """
    if not results:
        raise IdentificationError("no free-decay results to pool")
    g = float(results[0].details.get(q.g_m_s2, 9.81))
    parameters: dict[str, Estimate] = {}
    consistency: dict[str, float] = {}
    for key in (q.omega_rad_s, q.zeta):
        values = np.array([r[key].value for r in results])
        sigmas = np.array([max(r[key].half_width / Z95, 1e-300) for r in results])
        w = 1.0 / sigmas**2
        mean = float(np.sum(w * values) / np.sum(w))
        sigma = float(1.0 / math.sqrt(np.sum(w)))
        if values.size > 1:
            chi2 = float(np.sum(w * (values - mean) ** 2))
            birge = math.sqrt(chi2 / (values.size - 1))
            consistency[f"{key}_birge_ratio"] = birge
            sigma *= max(1.0, birge)
        half = Z95 * sigma
        parameters[key] = Estimate(mean, (mean - half, mean + half))
    omega = parameters[q.omega_rad_s]
    L = g / omega.value**2
    half_L = 2.0 * L / omega.value * omega.half_width
    pooled = {q.L_m: Estimate(L, (L - half_L, L + half_L)), **parameters}
    worst = max(results, key=lambda r: r.quality.rms_residual_rad)
    warnings = [w for r in results for w in r.warnings]
    for key, birge in consistency.items():
        if birge > 2.0:
            warnings.append(
                f"records disagree on {key.removesuffix('_birge_ratio')} (Birge ratio "
                f"{birge:.3g}); interval widened accordingly"
            )
    return IdentificationResult(
        experiment=FREE_DECAY.name,
        method=f"inverse-variance pooling of {len(results)} free-decay fits",
        parameters=pooled,
        quality=worst.quality,
        warnings=tuple(warnings),
        details={"records": [r.as_json() for r in results], **consistency},
    )
