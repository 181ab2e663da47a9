"""`avr-pss`: the conventional baseline (docs/model.md section 2, "Baselines").

- A static exciter (IEEE ST1A-like): u_f = K_A / (1 + s T_A) (Vt_ref - Vt + v_s),
  a non-windup lag held within [uf_min, uf_max] (the plant's field limits);
- a power system stabilizer on the speed deviation in pu (domega / ws):
  v_s = K_pss * s T_w / (1 + s T_w) * (1 + s T1)/(1 + s T2) * (1 + s T3)/(1 + s T4),
  clipped to [-vs_max, vs_max];
- an SVC voltage regulator: u_r = K_svc / (1 + s T_svc) (Vt_ref - Vt), a non-windup
  lag within [ur_min, ur_max] (the SVC rating), through the SVC's own lag Tr.

Vt is the measured SVC-bus voltage on the network in force (docs/model.md section 1);
Vt_ref is its operating-point value, and the exciter's reference is set so that the
lag starts at E_fd0 (no initial transient).

Default values: Kundur, *Power System Stability and Control* (McGraw-Hill, 1994),
Example 12.4 / 13.2 (thyristor exciter K_A = 200, T_R = 0.02 s; PSS K_STAB = 9.5,
T_W = 1.4 s, T1 = 0.154 s, T2 = 0.033 s, one lead-lag stage: the second stage here
is neutral, T3 = T4); SVC regulator: gain 20 pu/pu (a 5% slope, Kundur section 11.2.2)
and 0.05 s.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._network import prefault_stage
from .._parameters import _f
from .._plant import equilibrium_state, operating_field_voltage, terminal_voltage
from .._validate import is_concrete, require
from .base import AbstractController, ControllerOutput

__all__ = ["AvrPss"]

Scalar = Float[Array, "*batch"]


def _field(default: float):
    return eqx.field(default=default, converter=_f)


_KINDS = {
    "K_A": "log",
    "T_A": "log",
    "K_pss": "softplus",
    "T_w": "log",
    "T1": "log",
    "T2": "log",
    "T3": "log",
    "T4": "log",
    "vs_max": "log",
    "K_svc": "softplus",
    "T_svc": "log",
}


def _pinned(x, dx, lo, hi):
    """A lag's state held at a limit: at (or past) it and pushed outwards."""
    return ((x >= hi) & (dx > 0)) | ((x <= lo) & (dx < 0))


def _nonwindup(x, dx, lo, hi):
    """dx/dt of a lag whose state is held within [lo, hi]: no motion outwards at a
    limit (infinite limits: no limit)."""
    return jnp.where(_pinned(x, dx, lo, hi), 0.0, dx)


def _commanded(x, demand, dx, lo, hi):
    """The command reported to the plant: the lag's state, or the regulator's
    demand (the lag's input, beyond the limit) while the limiter holds the state.
    Under the hard limits the applied input is the same either way (the limit);
    the report then sees the limiter act (see `AvrPss`)."""
    return jnp.where(_pinned(x, dx, lo, hi), demand, x)


class AvrPss(AbstractController):
    """Static exciter + PSS + SVC voltage regulator (parameters in pu and s).

    Internal state: (exciter output u_f, washout state, lead-lag 1, lead-lag 2,
    SVC regulator output u_r). Diagnostics: (PSS output v_s, Vt - Vt_ref) in pu.

    Commanded inputs: the exciter and the SVC regulator are non-windup lags whose
    states stay at the limits (or past them by the solver's overshoot, up to 0.09
    pu), so as commands they would equal the applied inputs up to that overshoot:
    the peak command read as the ceiling (5.09 pu over 256 validation scenarios,
    where the exciter asks for 173 pu), and the time on a limit was right only
    because the overshoot exceeded `metrics.on_limit`'s 1e-9 pu (a state held
    exactly at the limit read as never on it). While a limiter holds its lag (state
    at the limit, the input pushing outwards) the commanded u_f is the regulator's
    demand K_A (Vt_ref - Vt + v_s) (the lag's input: the field voltage the exciter
    would settle to without a ceiling), and the commanded u_r is K_svc (Vt_ref -
    Vt); otherwise the lag's state. The plant clips the command to the same limits,
    so under the hard limits the applied inputs are unchanged; under the soft
    limiter of training the applied input then approaches the limit instead of
    sitting a softplus width inside it.
    """

    K_A: Scalar = _field(200.0)  # exciter gain (pu/pu)
    T_A: Scalar = _field(0.02)  # exciter / transducer time constant (s)
    K_pss: Scalar = _field(9.5)  # PSS gain (pu voltage per pu speed)
    T_w: Scalar = _field(1.4)  # washout (s)
    T1: Scalar = _field(0.154)  # lead-lag 1 (s)
    T2: Scalar = _field(0.033)
    T3: Scalar = _field(0.05)  # lead-lag 2 (neutral by default)
    T4: Scalar = _field(0.05)
    vs_max: Scalar = _field(0.2)  # PSS output limit (pu)
    K_svc: Scalar = _field(20.0)  # SVC regulator gain (pu susceptance per pu voltage)
    T_svc: Scalar = _field(0.05)  # SVC regulator time constant (s)

    n_internal = 5
    diagnostic_names = ("v_s", "Vt_err")
    conventional = True  # designed for the ceilings of a real exciter and SVC

    def __check_init__(self):
        vals = [getattr(self, n) for n in _KINDS]
        if not is_concrete(*vals):
            return
        for name, kind in _KINDS.items():
            v = np.asarray(getattr(self, name))
            if kind == "log":
                require((v > 0) & np.isfinite(v), "AvrPss", name, v, "must be > 0")
            else:
                require((v >= 0) & np.isfinite(v), "AvrPss", name, v, "must be >= 0")

    @classmethod
    def parameter_kinds(cls) -> dict[str, str]:
        return dict(_KINDS)

    def initial_internal(self, z0, plant, op, init):
        zero = jnp.zeros_like(z0[0])
        uf0 = operating_field_voltage(op, plant) + zero
        return jnp.stack([uf0, zero, zero, zero, zero])

    def _vt_ref(self, plant, op):
        z_e = equilibrium_state(op, plant)
        return terminal_voltage(z_e[0], z_e[2], z_e[3], prefault_stage(plant), plant)

    def label(self) -> str:
        return "AVR + PSS + SVC regulator"

    def __call__(self, t, z, s, stage, plant, op, trig=None):
        u_f, x_w, x_1, x_2, u_r = s[0], s[1], s[2], s[3], s[4]
        vt = terminal_voltage(z[0], z[2], z[3], stage, plant, trig)
        vt_err = self._vt_ref(plant, op) - vt
        w_pu = z[1] / plant.ws
        y_w = self.K_pss * (w_pu - x_w)  # washout output
        y_1 = x_1 + (self.T1 / self.T2) * (y_w - x_1)  # lead-lag 1 output
        y_2 = x_2 + (self.T3 / self.T4) * (y_1 - x_2)  # lead-lag 2 output
        v_s = jnp.clip(y_2, -self.vs_max, self.vs_max)
        v_ref = operating_field_voltage(op, plant) / self.K_A  # u_f(0) = E_fd0
        demand_f = self.K_A * (vt_err + v_ref + v_s)  # the exciter lag's input
        demand_r = self.K_svc * vt_err  # the SVC regulator lag's input
        du_f = (demand_f - u_f) / self.T_A
        du_r = (demand_r - u_r) / self.T_svc
        lim_f, lim_r = (plant.uf_min, plant.uf_max), (plant.ur_min, plant.ur_max)
        ds = jnp.stack(
            [
                _nonwindup(u_f, du_f, *lim_f),
                (w_pu - x_w) / self.T_w,
                (y_w - x_1) / self.T2,
                (y_1 - x_2) / self.T4,
                _nonwindup(u_r, du_r, *lim_r),
            ]
        )
        return ControllerOutput(
            _commanded(u_f, demand_f, du_f, *lim_f),
            _commanded(u_r, demand_r, du_r, *lim_r),
            ds,
            jnp.stack([v_s, -vt_err]),
        )
