"""Small-signal analysis of the multi-machine engine (`smibjax.grid.modes`,
`smibjax.grid.damping`, `python -m smibjax modes`) against independent references:
the classical machines' state matrix from a Kron-reduced network written here in
numpy, the SMIB swing-mode closed form, the nonlinear model's perturbed equilibrium,
central finite differences, and ANDES's EIG."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smibjax.grid.case import andes_swing, load_case
from smibjax.grid.damping import damping_loss, reference_modes
from smibjax.grid.loop import evaluate, state_labels
from smibjax.grid.modes import (
    linearize,
    modes,
    participation,
    transfer_function,
)
from smibjax.grid.network import stage_configs, stage_matrices
from smibjax.grid.operating import operating_point_traced
from smibjax.grid.params import set_params
from smibjax.grid.ybus import ybus

# one worker runs the module: its tests share the module fixtures' linearizations
# and their programs (under -n 2 a test on the other worker built them again)
pytestmark = pytest.mark.xdist_group("modes")


def operating_point(case):
    """The operating point (jitted: about twice as fast as the host entry here)."""
    op, pf = jax.jit(lambda: operating_point_traced(case))()
    assert bool(pf.converged)
    return op, pf


@pytest.fixture(scope="module")
def gencls():
    case = load_case("kundur-gencls")
    op, pf = operating_point(case)
    return case, op, pf, linearize(case, op)


@pytest.fixture(scope="module")
def smib():
    case = load_case("smib-gencls")
    op, pf = operating_point(case)
    return case, op, pf, linearize(case, op)


def _classical_a(case, op, pf):
    """A of classical machines from first principles: constant-impedance loads and
    the machines' Ra + j X'd added to the bus admittance matrix, every bus
    eliminated (Kron), Pe_i = Re(E_i conj(sum_j Y_ij E_j)) differentiated by hand;
    infinite buses (`case.sources`) are fixed-voltage nodes kept in the reduction.
    States ordered as the engine's labels (delta then omega per machine group)."""
    sysm = case.system
    sb = sysm.s_base
    wb = 2 * np.pi * sysm.f_base
    n = sysm.n_bus
    vm, va = np.asarray(pf.vm), np.asarray(pf.va)
    v = vm * np.exp(1j * va)
    Y = np.array(ybus(sysm))
    ld = sysm.loads
    for b, p, q in zip(
        np.asarray(ld.bus), np.asarray(ld.p), np.asarray(ld.q), strict=True
    ):
        Y[b, b] += (p - 1j * q) / vm[b] ** 2
    gb = np.asarray(sysm.generators.bus)
    lay = case.layout
    # machines: (generator position, H, D, mbase, z on system base)
    mach = []
    for m, gens in zip(case.machines, lay.machine_gen, strict=True):
        for k, g in enumerate(gens):
            z = (float(m.ra[k]) + 1j * float(m.xdp[k])) * sb / float(m.mbase[k])
            mach.append((g, float(m.H[k]), float(m.D[k]), float(m.mbase[k]), z))
    off = sum(op.sizes[: len(case.machines) + len(case.controllers)])
    for s, size in zip(
        case.svcs, op.sizes[-len(case.svcs) or len(op.sizes) :], strict=False
    ):
        # frozen SVCs: their admittance at rest is a fixed shunt
        x = np.asarray(op.y0[off : off + size]).reshape(len(s.state_names), -1)
        Y[np.asarray(s.bus), np.asarray(s.bus)] += np.asarray(s.admittance(x, sb))
        off += size
    pg = np.asarray(pf.p_gen) + 1j * np.asarray(pf.q_gen)
    e = []
    for g, _, _, _, z in mach:
        i_g = np.conj(pg[g] / v[gb[g]])
        e.append(v[gb[g]] + z * i_g)
    e = np.array(e)
    src = list(lay.source_gen)
    # extended network: buses, then machine internal nodes
    m_ = len(mach)
    Ye = np.zeros((n + m_, n + m_), dtype=complex)
    Ye[:n, :n] = Y
    for k, (g, _, _, _, z) in enumerate(mach):
        y = 1 / z
        b = gb[g]
        Ye[n + k, n + k] += y
        Ye[b, b] += y
        Ye[n + k, b] -= y
        Ye[b, n + k] -= y
    keep = list(range(n, n + m_)) + [gb[g] for g in src]
    elim = [i for i in range(n + m_) if i not in keep]
    Yr = Ye[np.ix_(keep, keep)] - Ye[np.ix_(keep, elim)] @ np.linalg.solve(
        Ye[np.ix_(elim, elim)], Ye[np.ix_(elim, keep)]
    )
    eall = np.concatenate([e, v[[gb[g] for g in src]]])
    G, B = Yr.real, Yr.imag
    mag, ang = np.abs(eall), np.angle(eall)
    dPe = np.zeros((m_, m_))  # dPe_i / d delta_j (pu system base)
    for i in range(m_):
        for j in range(len(eall)):
            if j == i:
                continue
            dij = ang[i] - ang[j]
            kij = mag[i] * mag[j] * (B[i, j] * np.cos(dij) - G[i, j] * np.sin(dij))
            if j < m_:
                dPe[i, j] = -kij
            dPe[i, i] += kij
    A = np.zeros((2 * m_, 2 * m_))
    for k, (_, H, D, mb, _) in enumerate(mach):
        A[k, m_ + k] = wb
        A[m_ + k, :m_] = -dPe[k] * (sb / mb) / (2 * H)
        A[m_ + k, m_ + k] = -D / (2 * H)
    return A, np.array([h for _, h, _, _, _ in mach]), dPe


def test_kundur_gencls_state_matrix_matches_kron_reduced_closed_form(gencls):
    case, op, pf, lin = gencls
    labels = state_labels(case)
    assert [lab[2] for lab in labels] == ["delta"] * 4 + ["omega"] * 4
    A_ref, _, _ = _classical_a(case, op, pf)
    scale = np.abs(A_ref).max()
    assert np.abs(lin.A - A_ref).max() < 1e-8 * scale
    ev = np.linalg.eigvals(lin.A)
    ev_ref = np.linalg.eigvals(A_ref)
    osc = ev_ref[np.abs(ev_ref.imag) > 1.0]
    assert len(osc) == 6  # three swing pairs; the other two are the zero modes
    err = [np.abs(ev - r).min() for r in osc]
    assert max(err) < 1e-8 * np.abs(ev_ref).max()
    assert np.sum(np.abs(ev) < 1e-6) == 2


def test_kundur_gencls_modes_two_local_one_inter_area_two_zero(gencls):
    case, op, pf, lin = gencls
    ms = modes(case, lin)
    em = [m for m in ms if m.kind == "electromechanical"]
    zero = [m for m in ms if m.kind == "zero"]
    assert len(em) == 3 and len(zero) == 2
    assert len(ms) == 5  # 3 pairs + 2 real zeros = 8 eigenvalues
    assert all(abs(m.eigenvalue) < 1e-5 and np.isnan(m.damping) for m in zero)
    inter = [m for m in em if m.scope == "inter-area"]
    local = [m for m in em if m.scope == "local"]
    assert len(inter) == 1 and len(local) == 2
    # D = 0: undamped oscillations, at the Kron closed form's frequencies
    assert all(abs(m.damping) < 1e-9 for m in em)
    assert inter[0].frequency < min(m.frequency for m in local)
    # inter-area: machines of area 1 (1:1, 2:1) against area 2 (3:1, 4:1)
    sh = inter[0].shape
    assert np.sign(sh["1:1"].real) == np.sign(sh["2:1"].real)
    assert np.sign(sh["3:1"].real) == np.sign(sh["4:1"].real)
    assert np.sign(sh["1:1"].real) != np.sign(sh["3:1"].real)
    # each local mode: the two machines of one area against each other
    pairs = sorted(
        tuple(sorted(sorted(m.shape, key=lambda g: -abs(m.shape[g]))[:2]))
        for m in local
    )
    assert pairs == [("1:1", "2:1"), ("3:1", "4:1")]


def test_participation_columns_sum_to_one(gencls):
    case, op, pf, lin = gencls
    lam, R = np.linalg.eig(lin.A)
    L = np.linalg.inv(R)
    P = participation(R, L)
    np.testing.assert_allclose(P.sum(axis=0), 1.0, rtol=1e-12)
    # the complex participations sum to 1 before the normalization (L R = I)
    np.testing.assert_allclose((R * L.T).sum(axis=0), 1.0, atol=1e-8)
    for m in modes(case, lin):
        assert sum(p for _, p in m.dominant) <= 1.0 + 1e-12


def test_smib_swing_mode_matches_synchronizing_coefficient(smib):
    """The SMIB case: one classical machine (1:1) against a classical machine of
    huge inertia (3:1, the infinite bus) through the SVC's bus. Its swing mode is
    lambda = -D/(4H) +- j sqrt(wb Ks / 2H - (D/4H)^2), Ks = dPe/ddelta on the
    machine base from the Kron-reduced network, so |lambda| = sqrt(wb Ks / 2H), up
    to the ratio of the inertias (H1/H2 ~ 1e-5); and the two-machine state matrix
    matches the closed form."""
    case, op, pf, lin = smib
    A_ref, H, dPe = _classical_a(case, op, pf)
    assert len(H) == 2 and H[1] > 1e4 * H[0]
    mb = float(case.machines[0].mbase[0])
    ks = dPe[0, 0] * case.system.s_base / mb
    wb = 2 * np.pi * case.system.f_base
    D = float(case.machines[0].D[0])
    em = [m for m in modes(case, lin) if m.kind == "electromechanical"]
    assert len(em) == 1
    lam = em[0].eigenvalue
    ev_ref = np.linalg.eigvals(A_ref)
    assert np.abs(ev_ref - lam).min() < 1e-8 * abs(lam)
    f_n = np.sqrt(wb * ks / (2 * H[0])) / (2 * np.pi)
    assert abs(abs(lam) / (2 * np.pi) - f_n) < 1e-4 * f_n
    assert abs(lam.real + D / (4 * H[0])) < 1e-4 * abs(lam.real)
    assert em[0].scope == "local" and em[0].frequency > 1.0
    assert sorted({m.kind for m in modes(case, lin)}) == [
        "electromechanical",
        "frozen",
        "other",
        "zero",
    ]


def test_dc_gain_matches_perturbed_nonlinear_equilibrium(smib):
    """The SMIB with its infinite-bus machine (3:1) held: G(0) of Pm -> delta and
    Pm -> Vt of machine 1:1 (`transfer_function` at s = 0 of the held system)
    against the nonlinear model's equilibria at Pm +- 1e-4 pu (Newton on the
    engine's vector field over the moving states)."""
    import dataclasses

    case, op, pf, lin = smib
    mats = stage_matrices(op.grid, stage_configs(op.grid, ()))
    labels = state_labels(case)
    still = ~np.any(lin.A != 0, axis=1)
    free = np.flatnonzero(~still & np.array([lab[1] != "3:1" for lab in labels]))
    i_d = labels.index(("GENCLS", "1:1", "delta"))
    n_gen = case.n_gen

    def f(y, dpm):
        u = {"Pm": jnp.zeros(n_gen).at[0].set(dpm)}
        dy, meas, _ = evaluate(case, op, mats, 0, y, u)
        return dy, meas["Vt"][0]

    jf = jax.jit(f)
    jac = jax.jit(jax.jacfwd(lambda y, d: f(y, d)[0]))

    def equilibrium(dpm):
        y = np.asarray(op.y0).copy()
        for _ in range(30):
            r = np.asarray(jf(y, dpm)[0])[free]
            if np.abs(r).max() < 1e-13:
                break
            J = np.asarray(jac(y, dpm))[np.ix_(free, free)]
            y[free] -= np.linalg.solve(J, r)
        assert np.abs(np.asarray(jf(y, dpm)[0])[free]).max() < 1e-13
        return y, float(jf(y, dpm)[1])

    h = 1e-4
    (yp, vp), (ym, vm_) = equilibrium(h), equilibrium(-h)
    fd_delta = (yp[i_d] - ym[i_d]) / (2 * h)
    fd_vt = (vp - vm_) / (2 * h)
    held = dataclasses.replace(
        lin, A=lin.A[np.ix_(free, free)], B=lin.B[free], C=lin.C[:, free]
    )
    g_delta = transfer_function(held, 0.0, ("delta", "1:1"), ("Pm", "1:1"))
    g_vt = transfer_function(held, 0.0, ("Vt", "1:1"), ("Pm", "1:1"))
    assert abs(g_delta.imag) < 1e-12 and abs(g_vt.imag) < 1e-12
    assert abs(g_delta.real - fd_delta) < 1e-6 * abs(fd_delta)
    assert abs(g_vt.real - fd_vt) < 1e-5 * abs(fd_vt) + 1e-9
    assert g_delta.real > 0.1  # rad per pu of mechanical power: a meaningful gain


def test_damping_loss_gradient_matches_central_differences():
    """d loss / d D of the classical Kundur machines (D shared by all four, equal
    at 1 pu: the equilibrium and the picks follow through operating_point_traced at
    two load factors) against central differences."""
    case0 = load_case("kundur-gencls")
    lfs = (1.0, 0.9)

    def loss(d):
        c = set_params(case0, {"GENCLS.D": d})
        return damping_loss(c, target=0.1, load_factors=lfs, reference=ref)

    ref = reference_modes(set_params(case0, {"GENCLS.D": 1.0}), lfs)
    assert [len(r) for r in ref] == [3, 3]
    vg = jax.jit(jax.value_and_grad(loss))
    v, g = vg(1.0)
    h = 1e-4
    fd = (vg(1.0 + h)[0] - vg(1.0 - h)[0]) / (2 * h)
    assert v > 0 and g < 0  # more damping lowers the loss
    assert abs(g - fd) < 1e-4 * abs(fd)
    # the loss is the squared hinge of the damping ratios of the reference modes
    # (computed concretely by `modes` at the same parameters), mean over the points
    hinge = [np.sum(np.maximum(0.1 - (-r.real / np.abs(r)), 0) ** 2) for r in ref]
    assert abs(v - np.mean(hinge)) < 1e-10
    vmax = jax.jit(
        lambda d: damping_loss(
            set_params(case0, {"GENCLS.D": d}),
            load_factors=lfs,
            reference=ref,
            reduce="max",
        )
    )(1.0)
    assert abs(vmax - max(hinge)) < 1e-10


# --- the full Kundur system (GENROU, exciters, PSS) ------------------------------

ANDES_NOPSS_INTER_AREA = (0.62, 0.002)  # Hz, damping ratio: the case author's run


@pytest.fixture(scope="module")
def kundur_modes():
    """The modes of Kundur's case with and without stabilizers in ANDES's swing
    equation (`andes_swing`: no speed factor; "kundur-nopss", "kundur"), and of the
    case without stabilizers in PSS/E's ("kundur-nopss psse", the default)."""
    out = {}
    for name in ("kundur-nopss", "kundur"):
        case = andes_swing(load_case(name))
        op, _ = operating_point(case)
        out[name] = modes(case, linearize(case, op))
    case = load_case("kundur-nopss")
    op, _ = operating_point(case)
    out["kundur-nopss psse"] = modes(case, linearize(case, op))
    return out


def test_pss_damps_the_inter_area_mode(kundur_modes):
    inter = {
        k: [m for m in v if m.kind == "electromechanical" and m.scope == "inter-area"]
        for k, v in kundur_modes.items()
    }
    assert len(inter["kundur-nopss"]) == 1 and len(inter["kundur"]) == 1
    z0, z1 = inter["kundur-nopss"][0].damping, inter["kundur"][0].damping
    assert 0 < z0 < 0.01  # barely damped without the stabilizers
    assert z1 > 0.1  # well damped with them
    f0 = inter["kundur-nopss"][0].frequency
    f_a, z_a = ANDES_NOPSS_INTER_AREA
    assert abs(f0 - f_a) < 0.01 * f_a
    assert abs(z0 - z_a) < 0.01
    # PSS/E's speed factor: d/d omega of (Pm - D omega)/(1 + omega) at rest is
    # -(Pm + D), a damping Pm (pu, machine base) on every machine: about Pm / (4 H
    # omega_n) = 0.78 / (4 x 6.175 x 3.9) = 0.008 more damping ratio on this mode
    # (measured 0.0022 -> 0.0104), the frequency the same
    zp = inter["kundur-nopss psse"][0]
    assert 0.006 < zp.damping - z0 < 0.010, (zp.damping, z0)
    assert abs(zp.frequency - f0) < 1e-3 * f0
    local = [
        m
        for m in kundur_modes["kundur-nopss"]
        if m.kind == "electromechanical" and m.scope == "local"
    ]
    assert len(local) == 2 and all(1.0 < m.frequency < 1.3 for m in local)


def test_against_andes_eig_live(kundur_modes):
    andes = pytest.importorskip("andes")
    from smibjax.grid.case import case_files

    raw, dyr = case_files("kundur-nopss")
    ss = andes.load(
        str(raw), addfile=str(dyr), setup=True, no_output=True, default_config=True
    )
    ss.PFlow.run()
    ss.EIG.run()
    mu = np.asarray(ss.EIG.mu)
    em = [m for m in kundur_modes["kundur-nopss"] if m.kind == "electromechanical"]
    for m in em:
        k = np.argmin(np.abs(mu - m.eigenvalue))
        f_a = mu[k].imag / (2 * np.pi)
        z_a = -mu[k].real / abs(mu[k])
        assert abs(m.frequency - f_a) < 0.01 * f_a
        assert abs(m.damping - z_a) < 0.01


# --- the command ------------------------------------------------------------------


def test_cli_modes_writes_table_json_csv_plot(tmp_path, capsys):
    from smibjax.cli import main

    out, csvp, png = tmp_path / "m.json", tmp_path / "m.csv", tmp_path / "m.png"
    rc = main(
        [
            "modes",
            "--case",
            "kundur-gencls",
            "--set",
            "GENCLS.D=2",
            "--out",
            str(out),
            "--csv",
            str(csvp),
            "--plot",
            str(png),
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "inter-area" in text and text.count("local") == 2
    data = json.loads(out.read_text())
    assert data["set"] == {"GENCLS.D": 2.0}
    # the same parameter from a --gains file gives the same modes
    gains = tmp_path / "gains.toml"
    gains.write_text('"GENCLS.D" = 2.0\n')
    out2 = tmp_path / "m2.json"
    assert (
        main(
            [
                "modes",
                "--case",
                "kundur-gencls",
                "--gains",
                str(gains),
                "--out",
                str(out2),
            ]
        )
        == 0
    )
    assert json.loads(out2.read_text())["modes"] == data["modes"]
    kinds = [m["kind"] for m in data["modes"]]
    assert kinds.count("electromechanical") == 3
    em = [m for m in data["modes"] if m["kind"] == "electromechanical"]
    assert all(m["damping"] > 0 for m in em)  # D = 2 damps every swing mode
    rows = csvp.read_text().splitlines()
    assert len(rows) == 1 + len(data["modes"])
    assert len(rows[0].split(",")) == 7 + len(data["states"])
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_cli_modes_sweep(tmp_path, capsys):
    from smibjax.cli import main

    out, png = tmp_path / "s.json", tmp_path / "s.png"
    rc = main(
        [
            "modes",
            "--case",
            "kundur-gencls",
            "--sweep",
            "GENCLS.D=0:4:3",
            "--out",
            str(out),
            "--plot",
            str(png),
        ]
    )
    assert rc == 0
    data = json.loads(out.read_text())
    assert data["values"] == [0.0, 2.0, 4.0]
    assert len(data["modes"]) == 3
    for m in data["modes"]:
        assert m["damping"][0] == pytest.approx(0.0, abs=1e-9)
        assert m["damping"][0] < m["damping"][1] < m["damping"][2]
    assert png.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--case", "nosuch"], "--case 'nosuch'"),
        (["--case", "kundur-gencls", "--set", "GENCLS.XX=1"], "GENCLS.XX"),
        (["--case", "kundur-gencls", "--sweep", "GENCLS.D=1:0:3"], "reversed"),
        (["--case", "kundur-gencls", "--sweep", "GENCLS.D=0:1"], "PARAM=lo:hi:n"),
        (["--case", "kundur-gencls", "--sweep", "GENCLS.D=0:1:x"], "an integer"),
        (["--case", "kundur-gencls", "--sweep", "FOO.K=0:1:3"], "FOO"),
        (["--case", "kundur-gencls", "--gains", "GAINS_NAN"], "is not a finite number"),
        (["--case", "kundur-gencls", "--gains", "GAINS_LIST"], "must be a table"),
        (["--case", "kundur-gencls", "--gains", "GAINS_BAD"], "GENCLS.XX"),
    ],
)
def test_cli_modes_bad_input_one_line_exit_2_nothing_written(
    tmp_path, capsys, argv, words
):
    from smibjax.cli import main

    out = tmp_path / "m.json"
    files = {
        "GAINS_NAN": '{"GENCLS.D": NaN}',
        "GAINS_LIST": "[1, 2]",
        "GAINS_BAD": '{"GENCLS.XX": 1.0}',
    }
    for key, text in files.items():
        (tmp_path / f"{key}.json").write_text(text)
    argv = [str(tmp_path / f"{a}.json") if a in files else a for a in argv]
    rc = main(["modes", *argv, "--out", str(out), "--plot", str(tmp_path / "p.png")])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and err.startswith("smibjax: error:")
    assert words in err
    assert not out.exists() and not (tmp_path / "p.png").exists()


@jax.jit  # one program for the three gain sets, not ~100 operations run eagerly each
def _loop_jacobian(y, loop):
    from smibjax._closed_loop import closed_loop_vector_field

    return jax.jacfwd(lambda y: closed_loop_vector_field(0.0, y, loop))(y)


@pytest.mark.parametrize("beta", [(-1.0, -1.0), (-2.0, -1.0), (50.0, 50.0)])
def test_the_paper_cases_linearization_has_the_manifold_roots(beta):
    """Issue 29 item 5: the Jacobian of the SMIB's closed loop (ASC, oracle
    adaptation, at the equilibrium with the true estimates) has the roots of the
    manifold's error dynamics M s^2 + (D - kappa) s - kappa = 0, kappa = 1/beta1 +
    1/beta2 (docs/model.md section 2): the saddle +0.24 1/s for beta = 50."""
    import smibjax as sj
    from smibjax._closed_loop import ClosedLoop, initial_state
    from smibjax._parameters import InitialEstimates

    g = sj.Gains.paper("asc", beta1=beta[0], beta2=beta[1])
    plant, op = sj.Plant(), sj.OperatingPoint()
    loop = ClosedLoop(g, sj.Fault(), plant, op)
    y = initial_state(op, plant, InitialEstimates(), loop.controller)
    y = y.at[4].set(-plant.D).at[5].set(plant.Pm)  # the estimates at the truth
    A = _loop_jacobian(y, loop)[:6, :6]
    lam = np.linalg.eigvals(np.asarray(A))
    M = 2 * float(plant.H) / (2 * np.pi * float(plant.f))
    kappa = 1 / beta[0] + 1 / beta[1]
    for root in np.roots([M, float(plant.D) - kappa, -kappa]):
        assert np.min(np.abs(lam - root)) < 1e-8 * max(1.0, abs(root)), (root, lam)


# --- the scope of a mode from its shape, and short machine lists (issue 50) -------


def _shape(values: dict) -> dict:
    return {g: complex(v) for g, v in values.items()}


def test_scope_two_areas_one_group_each_is_inter_area_even_where_areas_overlap():
    """Issue 50: a mode of two opposing groups whose areas overlap (a machine of
    each area swinging with the other area) was 'local'; the groups' main areas
    differ, so it is inter-area."""
    from smibjax.grid.modes import _scope

    names = ["1", "2", "3", "4", "5", "6"]
    areas = [1, 1, 1, 2, 2, 2]
    shape = _shape({"1": 1.0, "2": 0.9, "4": 0.3, "3": -0.25, "5": -0.8, "6": -0.7})
    assert _scope(shape, names, areas) == "inter-area"
    # two machines of one area against each other, the rest still: local
    shape = _shape({"1": 1.0, "2": -0.8, "3": 0.05, "4": 0.0, "5": 0.01, "6": 0.0})
    assert _scope(shape, names, areas) == "local"
    # all in phase: common
    assert _scope(_shape(dict.fromkeys(names, 1.0)), names, areas) == "common"


def test_scope_of_a_mode_spread_over_many_machines_is_inter_area():
    """24 of 48 machines taking part (a 0.22 Hz NPCC mode) is inter-area, even when
    both groups' main area is the same; 3 of 48 against each other is local."""
    from smibjax.grid.modes import _scope

    names = [str(k) for k in range(48)]
    areas = [1] * 40 + [2] * 8
    values = {g: 0.01 for g in names}
    for k in range(24):
        values[str(k)] = 1.0 if k % 2 else -0.6
    assert _scope(_shape(values), names, areas) == "inter-area"
    values = {g: 0.01 for g in names}
    values.update({"0": 1.0, "1": -0.5, "2": -0.4})
    assert _scope(_shape(values), names, areas) == "local"


def test_dominant_text_is_the_first_five_and_a_count():
    from smibjax.grid.modes import Mode, dominant_text

    shape = _shape({f"{k}:1": 1.0 - k / 30 for k in range(24)})
    m = Mode(
        index=0,
        eigenvalue=complex(-0.1, 1.4),
        frequency=0.22,
        damping=0.07,
        kind="electromechanical",
        scope="inter-area",
        dominant=(),
        shape=shape,
    )
    assert dominant_text(m) == "0:1, 1:1, 2:1, 3:1, 4:1 and 19 more"
    small = Mode(**{**m.__dict__, "shape": _shape({"1:1": 1.0, "2:1": -0.5})})
    assert dominant_text(small) == "1:1, 2:1"


def test_active_limits_names_a_governor_sitting_on_its_valve_limit():
    """Issue 50: on ANDES's IEEE 14 a governor sits exactly on its lower limit, which
    the linearization and another program treat differently; `active_limits` names
    each such limiter. Kundur's TGOV1 at 1:1 with VMIN moved onto its valve
    position is found (and only it); with VMIN back below, nothing is."""
    from smibjax.grid.loop import state_labels
    from smibjax.grid.modes import active_limits
    from smibjax.grid.params import set_params

    case = load_case("kundur")
    op, _ = operating_point(case)
    assert active_limits(case, op) == []
    k = state_labels(case).index(("TGOV1", "1:1", "x_v"))
    xv = float(op.y0[k])
    on = set_params(case, {"TGOV1[1:1].VMIN": xv})
    op_on, _ = operating_point(on)
    assert float(op_on.y0[k]) == pytest.approx(xv, rel=1e-12)
    assert active_limits(on, op_on) == [("TGOV1", "1:1", "x_v", "VMIN", xv)]
    off = set_params(case, {"TGOV1[1:1].VMIN": xv - 1e-3})
    assert active_limits(off, operating_point(off)[0]) == []


def test_modes_warns_once_per_active_limit_and_states_the_convention(
    monkeypatch, capsys
):
    from smibjax.cli import modes as cli_modes
    from smibjax.grid import modes as grid_modes

    monkeypatch.setattr(
        grid_modes,
        "active_limits",
        lambda case, op: [("TGOV1", "6:1", "x_v", "VMIN", 0.3)],
    )
    cli_modes.warn_active_limits(None, None)
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (
        "smibjax: warning: TGOV1 6:1: x_v sits on its limit VMIN = 0.3 at the "
        "operating point"
    )
    assert err[1].startswith("smibjax: warning: the linearization takes JAX's")
    assert "--set MODEL[BUS:ID].PARAM=VALUE" in err[1] and len(err) == 2
    monkeypatch.setattr(grid_modes, "active_limits", lambda case, op: [])
    cli_modes.warn_active_limits(None, None)
    assert capsys.readouterr().err == ""


def test_the_documented_limit_convention_is_what_jax_differentiates():
    """`LIMIT_CONVENTION`: a non-windup lag exactly on its lower limit at rest
    (input = state = limit): its state derivative is free (-1/T per unit of state),
    its clipped output moves at half the free gain (jnp.clip at a tie)."""
    from smibjax.grid.devices._blocks import lag_nonwindup
    from smibjax.grid.modes import LIMIT_CONVENTION

    lo, hi, T = 0.3, 1.0, 0.5

    def f(x, u):
        y, dx = lag_nonwindup(x, u, 1.0, T, lo, hi)
        return jnp.stack([y, dx])

    J = jax.jacfwd(f, argnums=(0, 1))(jnp.asarray(lo), jnp.asarray(lo))
    dy_dx, ddx_dx = (float(v) for v in J[0])
    assert dy_dx == 0.5  # half the free gain: neither binding (0) nor free (1)
    assert ddx_dx == pytest.approx(-1 / T)  # the state free
    assert float(J[1][1]) == pytest.approx(1 / T)
    assert "half its free gain" in LIMIT_CONVENTION and "free" in LIMIT_CONVENTION
