"""Periodic orbits by shooting: fixed points of the k-th iterate of the stroboscopic map.

A period-k orbit is a state x at drive phase 0 with P^k(x) = x.  Newton's method solves
(J - I) dx = x - P^k(x) with the finite-difference Jacobian of
:class:`analysis.dynamics.period_map.PeriodMap`, halving a step that does not lower the
residual.  The orbit's Floquet multipliers are the eigenvalues of J at the solution; it
is stable when all lie inside the unit circle.  Sizes are measured in theta [rad] and
theta' / Omega [rad per radian of drive phase], so both components count alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.dynamics.period_map import Linearisation, MapError, PeriodMap

NEWTON_TOLERANCE = 1e-10  # residual |P^k(x) - x| in scaled units (rad)
MAX_NEWTON_ITERATIONS = 30
MAX_HALVINGS = 8


class ShootingError(RuntimeError):
    """Newton's method found no periodic orbit; the message says where and why."""


@dataclass(frozen=True)
class PeriodicOrbit:
    """A fixed point of P^k at one parameter value, with its linearisation there."""

    value: float
    state: np.ndarray
    periods: int
    linearisation: Linearisation
    residual: float  # |P^k(x) - x|, scaled units
    iterations: int

    @property
    def multipliers(self) -> np.ndarray:
        """Floquet multipliers, largest modulus first."""
        return self.linearisation.multipliers

    @property
    def stable(self) -> bool:
        """All multipliers strictly inside the unit circle."""
        return bool(np.all(np.abs(self.multipliers) < 1.0))


def state_scale(period_map: PeriodMap, value: float) -> np.ndarray:
    """Divisors making (theta, theta') comparable: (1, Omega)."""
    return np.array([1.0, period_map.drive_rate(value)])


def find_periodic_orbit(
    period_map: PeriodMap,
    value: float,
    guess: np.ndarray,
    *,
    tolerance: float = NEWTON_TOLERANCE,
    max_iterations: int = MAX_NEWTON_ITERATIONS,
) -> PeriodicOrbit:
    """Newton's method for P^k(x) = x at ``value`` from ``guess`` (theta, theta').

    Raises ShootingError naming the parameter value, the last state and residual when it
    does not converge, the Jacobian is singular (a multiplier at +1: a fold), or the
    integrator stops on the way.
    """
    x = np.asarray(guess, dtype=float).copy()
    scale = state_scale(period_map, value)
    where = f"{period_map.parameter} = {value:.10g}, period {period_map.periods}"
    try:
        lin = period_map.linearise(value, x)
        residual = float(np.linalg.norm((lin.image - x) / scale))
        for iteration in range(1, max_iterations + 1):
            matrix = lin.jacobian - np.eye(2)
            if not np.all(np.isfinite(matrix)) or abs(np.linalg.det(matrix)) < 1e-14:
                raise ShootingError(
                    f"Newton's method stopped at {where}: J - I is singular (a multiplier "
                    f"at +1, a fold) at (theta, theta') = ({x[0]:.6g}, {x[1]:.6g})"
                )
            step = np.linalg.solve(matrix, x - lin.image)
            for _ in range(MAX_HALVINGS + 1):
                trial = x + step
                trial_lin = period_map.linearise(value, trial)
                trial_residual = float(np.linalg.norm((trial_lin.image - trial) / scale))
                if trial_residual < residual or residual < tolerance:
                    break
                step = 0.5 * step
            else:
                raise ShootingError(
                    f"Newton's method did not converge at {where}: no step lowers the "
                    f"residual {residual:.3g} at (theta, theta') = ({x[0]:.6g}, {x[1]:.6g})"
                )
            x, lin, residual = trial, trial_lin, trial_residual
            if residual < tolerance:
                return PeriodicOrbit(value, x, period_map.periods, lin, residual, iteration)
    except MapError as error:
        raise ShootingError(f"Newton's method stopped at {where}: {error}") from None
    raise ShootingError(
        f"Newton's method did not converge at {where} in {max_iterations} iterations: "
        f"residual {residual:.3g} at (theta, theta') = ({x[0]:.6g}, {x[1]:.6g})"
    )
