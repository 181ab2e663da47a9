"""The paper's closed loop at rest while the faulted circuit is out (issue 33): the
rest point (delta*, E*, B*, th_hat*) of the plant on the post-fault network (X2 = 2 XL)
under the paper's law, which keeps its pre-fault model (X2 = XL), and the offset
delta* - delta_e (rad) that decides whether a run can settle before its line
recloses. The derivation is in this folder's README ("The floor, derived"); the
functions below are its equations in NumPy, independent of smibjax's code (only the
plant's numbers are read from `smibjax.Plant` and `smibjax.OperatingPoint`).

    python studies/paper_heldout/floor.py

prints, for the gain sets of this study, the rest point and its leading-order form,
and the smallest offsets of random gain sets the paper config's tuner may choose (both
beta negative, and mixed signs); writes floor.json here. Stability of a rest point
and whether a run reaches it: tests/test_paper_floor.py (the simulator's own
Jacobian and runs).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
from scipy.optimize import brentq, root

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent


@dataclasses.dataclass(frozen=True)
class Case:
    """The plant (pu, s; paper defaults), the controller's operating point
    (delta_e in rad, Pm_ref in pu) and the true mechanical power Pm (pu)."""

    H: float = 5.0
    D: float = 0.2
    T0: float = 4.0
    V: float = 1.0
    Xd: float = 1.1
    Xdp: float = 0.2
    XT: float = 0.1
    XL: float = 0.2
    f: float = 60.0
    Pm: float = 1.0
    delta_e: float = 0.4964
    Pm_ref: float = 1.0

    @property
    def X1(self) -> float:  # generator side of the SVC bus, X'd + XT
        return self.Xdp + self.XT

    @property
    def M(self) -> float:  # inertia coefficient 2H/ws (s^2/rad)
        return 2 * self.H / (2 * math.pi * self.f)

    @property
    def Xs(self) -> float:  # the controller's (pre-fault) X1 + XL
        return self.X1 + self.XL

    @property
    def Xs_post(self) -> float:  # the true post-fault X1 + 2 XL
        return self.X1 + 2 * self.XL


def spow(y, a):
    """sign(y) |y|^a."""
    return np.sign(y) * np.abs(y) ** a


def model_powers(B, c: Case):
    """At rest on the post-fault network with electrical power Pm (E V sin delta =
    Pm R'(B), R'(B) = Xs' - X1 2XL B): the controller's x3 = E V sin delta / Xs,
    x4 = Mt x3 with Mt = X1 XL B / R(B), R(B) = Xs - X1 XL B, and its electrical
    power x3 + x4 = Pm R'/R (pu), with Mt (dimensionless)."""
    r_post = c.Xs_post - c.X1 * 2 * c.XL * B
    r_pre = c.Xs - c.X1 * c.XL * B
    x3 = c.Pm * r_post / c.Xs
    mt = c.X1 * c.XL * B / r_pre
    return x3, mt * x3, c.Pm * r_post / r_pre, mt


def model_error_rate(delta, B, c: Case):
    """q (pu/s): the rate of x3 that the pre-fault model predicts at the post-fault
    rest, (Xd - X'd)(1/Xs - 1/Xs')(V^2 sin delta cos delta - Pm R'(B)) / (Xs T0)
    (the true rate is 0)."""
    r_post = c.Xs_post - c.X1 * 2 * c.XL * B
    k = (c.Xd - c.Xdp) * (1 / c.Xs - 1 / c.Xs_post) / (c.Xs * c.T0)
    return k * (c.V**2 * math.sin(delta) * math.cos(delta) - c.Pm * r_post)


def _phis(e1, B, sigma, g: dict, c: Case):
    """(phi1, phi2) from the evolution law at rest: b_i (model rate of x_(i+2)) +
    sigma = spow(-phi_i/T_i, alpha), sigma = xdot2_hat = (th2 - x3 - x4)/M."""
    q = model_error_rate(c.delta_e + e1, B, c)
    mt = model_powers(B, c)[3]
    a = g["alpha"]
    phi1 = -g["T1"] * spow(sigma + g["beta1"] * q, 1 / a)
    phi2 = -g["T2"] * spow(sigma + g["beta2"] * mt * q, 1 / a)
    return phi1, phi2


def residual(v, g: dict, c: Case):
    """The three rest equations in (e1 = delta - delta_e (rad), B (pu), sigma
    (1/s^2... pu/(s^2/rad))): phi1 and phi2 as the macro-variables define them and as
    the evolution law holds them, and the rest of th_hat2."""
    e1, B, sigma = v
    x3, x4, p_mod, _ = model_powers(B, c)
    phi1, phi2 = _phis(e1, B, sigma, g, c)
    c1, c2 = g.get("c1", 1.0), g.get("c2", 1.0)
    th2 = p_mod + c.M * sigma
    return np.array(
        [
            c1 * e1 + g["beta1"] * (x3 - c.Pm_ref) - phi1,
            c2 * e1 + g["beta2"] * x4 - phi2,
            phi1 + phi2 - c.M * g["k2"] * spow(th2 - c.Pm, g["alpha"]),
        ]
    )


def leading_order(beta1: float, beta2: float, c: Case = Case()) -> dict:
    """The rest point with phi1 = phi2 = 0 (the limit T1, T2 -> 0 or k2 = 0 with
    q = 0): B_c solves beta1 (x3(B) - Pm_ref) = beta2 x4(B), and
    delta* - delta_e = -beta1 (x3(B_c) - Pm_ref) (rad)."""

    def gap(B):
        x3, x4, _, _ = model_powers(B, c)
        return beta1 * (x3 - c.Pm_ref) - beta2 * x4

    b_sing = c.Xs / (c.X1 * c.XL)  # R(B) = 0
    grid = np.linspace(-5.0, b_sing - 1e-6, 4001)
    vals = gap(grid)
    roots = [
        brentq(gap, grid[i], grid[i + 1], xtol=1e-15)
        for i in range(len(grid) - 1)
        if np.sign(vals[i]) != np.sign(vals[i + 1])
    ]
    # the branch that continues B = B0 = 0 as the model error vanishes: smallest |B|
    B = min(roots, key=abs)
    x3 = model_powers(B, c)[0]
    return {"B": B, "offset": -beta1 * (x3 - c.Pm_ref)}


def rest_point(g: dict, c: Case = Case()) -> dict:
    """The closed loop's rest point on the post-fault network for gains `g` (the
    paper's names; c1, c2 default 1): delta (rad), E (pu), B (pu), th_hat =
    (th1, th2) = (-D, th2), (phi1, phi2) and offset = delta - delta_e (rad). Needs
    k1 > 0 for th1 = -D (k1 = 0 leaves th1 free; it does not enter the rest)."""
    lo = leading_order(g["beta1"], g["beta2"], c)
    sol = root(residual, [lo["offset"], lo["B"], 0.0], args=(g, c), tol=1e-15)
    v = sol.x
    for _ in range(3):  # Newton polish (central-difference Jacobian)
        J = np.empty((3, 3))
        for j in range(3):
            h = 1e-7 * max(1.0, abs(v[j]))
            d = np.zeros(3)
            d[j] = h
            J[:, j] = (residual(v + d, g, c) - residual(v - d, g, c)) / (2 * h)
        v = v - np.linalg.solve(J, residual(v, g, c))
    e1, B, sigma = (float(x) for x in v)
    if np.max(np.abs(residual(v, g, c))) > 1e-12:
        raise RuntimeError(f"no rest point found for {g}: {sol.message}")
    delta = c.delta_e + e1
    x3, _, p_mod, _ = model_powers(B, c)
    phi1, phi2 = _phis(e1, B, sigma, g, c)
    return {
        "delta": delta,
        "E": x3 * c.Xs / (c.V * math.sin(delta)),
        "B": B,
        "th_hat": (-c.D, p_mod + c.M * sigma),
        "phi": (float(phi1), float(phi2)),
        "offset": e1,
    }


def load_gains(path: Path) -> dict:
    """The gains table of a smibjax gains file."""
    return {k: float(v) for k, v in json.loads(Path(path).read_text())["gains"].items()}


GAIN_SETS = {
    "paper_grad_gains.json": HERE / "paper_grad_gains.json",
    "paper_seed1_gains.json": HERE / "paper_seed1_gains.json",
    "paper_1202_gains.json": HERE / "paper_1202_gains.json",
    "bfd8280_gains.json": HERE / "bfd8280_gains.json",
}


MIXED = {"beta1": -0.1362, "beta2": 0.2366, "T1": 0.0036, "T2": 7.83, "alpha": 0.7023}
MIXED |= {"k2": 6.4508}  # (gamma1 = gamma2 = 5, k1 = 1: they do not enter the rest)


def admissible_search(signs: str, n: int = 2000, seed: int = 0) -> list[dict]:
    """Rest points of n random gain sets the paper config's tuner may choose:
    |beta_i| in [0.1, 100] (`gains.beta_abs_min`), `signs` "negative" (both < 0) or
    "mixed" (one of each) with 1/beta1 + 1/beta2 < 0 (a stable manifold), T1 in
    [0.002, 1], alpha in [0.6, 1] (the config's bounds), T2 in [1e-3, 100] and k2 0
    or in [1e-3, 100] (only positive by `Gains`' checks), log-uniform where positive.
    Returns {offset (rad), B (pu), gains} per set whose rest point was found, by
    |offset|."""
    rng = np.random.default_rng(seed)
    rows = []
    while n > 0:
        b = np.exp(rng.uniform(math.log(0.1), math.log(100.0), 2))
        b = -b if signs == "negative" else b * np.array([-1.0, 1.0])[rng.permutation(2)]
        if 1 / b[0] + 1 / b[1] >= 0:
            continue
        n -= 1
        k2 = math.exp(rng.uniform(math.log(1e-3), math.log(100.0)))
        g = {
            "beta1": float(b[0]),
            "beta2": float(b[1]),
            "T1": math.exp(rng.uniform(math.log(0.002), 0.0)),
            "T2": math.exp(rng.uniform(math.log(1e-3), math.log(100.0))),
            "alpha": rng.uniform(0.6, 1.0),
            "k2": k2 if rng.uniform() < 0.5 else 0.0,
        }
        try:
            r = rest_point(g)
        except (RuntimeError, ValueError, np.linalg.LinAlgError):
            continue
        rows.append({"offset": r["offset"], "B": r["B"], "gains": g})
    return sorted(rows, key=lambda r: abs(r["offset"]))


def main() -> None:
    out = {}
    sets = {name: load_gains(path) for name, path in GAIN_SETS.items()}
    for name, g in {**sets, "MIXED (tests/test_paper_floor.py)": MIXED}.items():
        r = rest_point(g)
        lo = leading_order(g["beta1"], g["beta2"])
        out[name] = {"rest": r, "leading_order": lo}
        print(
            f"{name:34} offset {r['offset']:+.6f} rad (leading order "
            f"{lo['offset']:+.6f}), B* {r['B']:.4f}, th2* {r['th_hat'][1]:.4f}"
        )
    for bmin in (0.1, 0.05):
        lo = leading_order(-bmin, -bmin)
        out[f"leading order, beta1 = beta2 = -{bmin:g}"] = lo
        print(f"leading order beta1 = beta2 = -{bmin:g}: offset {lo['offset']:.6f} rad")
    for signs in ("negative", "mixed"):
        rows = admissible_search(signs)
        inside = [r for r in rows if abs(r["offset"]) < 0.01]
        out[f"random admissible sets, beta {signs}"] = {
            "found": len(rows),
            "inside_band": len(inside),
            "smallest": rows[:10],
        }
        print(
            f"beta {signs}: {len(rows)} rest points, {len(inside)} inside 0.01 rad; "
            f"smallest |offset| {abs(rows[0]['offset']):.5f} rad (B* {rows[0]['B']:.3f})"
        )
    (HERE / "floor.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
