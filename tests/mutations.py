"""Deliberate breakages, one at a time, against the tests that must catch them.

    python tests/mutations.py                 # every mutant (tens of minutes on 2 cores)
    python tests/mutations.py --only NAME ... # some (names or fnmatch patterns)
    python tests/mutations.py --list          # the list, nothing run

Each mutant is (name, file, exact old text, new text, pytest selection, why). The script
copies the repository to a temporary directory (without .git and caches), replaces the
old text by the new one in the copy (the old text must occur exactly once: a mutant whose
text has moved is reported `stale`, never silently skipped), runs the selection there with
PYTHONPATH pointing to the copy's src (it checks that `smibjax` is imported from the copy)
and records `killed` (pytest exit status 1: a test failed), `survived` (status 0) or
`error` (any other status: collection error, no such test). The real tree is never
touched. It prints a table and writes tests/mutations.json (--json to change).

Not part of .ci/run and not collected by pytest (the file name does not start with
test_). The compiled-program cache of all copies is shared in $TMPDIR/smibjax-mutants-cache
(the mutated programs hash differently, so a mutant never reuses a stale program).
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[1]


class Mutant(NamedTuple):
    name: str
    file: str  # relative to the repository root
    old: str  # exact text, must occur once
    new: str
    select: tuple[str, ...]  # pytest node ids / paths that must fail
    why: str


GRAD = "tests/test_gradients.py"
SIM_REF = (
    "tests/test_simulate.py::test_trajectory_matches_independent_scipy_integration"
)
SIM_OTHER = "tests/test_simulate.py::test_other_scenarios_match_scipy"

PF = "tests/test_powerflow.py::"
PSSE = "src/smibjax/grid/psse.py"
PSSE_T = "tests/test_psse.py"

CONTROLS = "tests/test_grid_controls.py"
GOVPSS = "tests/test_grid_govpss.py"

MUTANTS = [
    # -- the stop-gradient on step lengths (_stepping.py) --------------------------
    Mutant(
        "rigidsteps-removed",
        "src/smibjax/_solve.py",
        "        RigidSteps(pid), jump_ts=jumps if has_jumps else None",
        "        pid, jump_ts=jumps if has_jumps else None",
        (f"{GRAD}::test_state_sensitivity_to_clearing_time_across_reclosure",),
        "the adaptive controller without RigidSteps: d/dt_clear wrong after t_reclose",
    ),
    Mutant(
        "rigidsteps-no-stop-gradient",
        "src/smibjax/_stepping.py",
        "next_t1 = next_t0 + lax.stop_gradient(next_t1 - next_t0)",
        "next_t1 = next_t1",
        (f"{GRAD}::test_state_sensitivity_to_clearing_time_across_reclosure",),
        "RigidSteps kept but its stop_gradient on proposed step lengths removed",
    ),
    # -- tuner resume ----------------------------------------------------------------
    Mutant(
        "resume-restarts",
        "tuning/loop.py",
        "    if resume:\n        state = load_checkpoint(out, opt, raw0)",
        "    if False:\n        state = load_checkpoint(out, opt, raw0)",
        ("tests/test_tuning.py::test_resume_trains_only_the_remaining_steps",),
        "--resume ignores the checkpoint and trains from step 0 (deterministic run: "
        "same gains and losses)",
    ),
    # -- control law (controllers/synergetic/law.py) ------------------------------
    Mutant(
        "uf-law-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "- evolution(phi1, gains.T1, a, layer)",
        "+ evolution(phi1, gains.T1, a, layer)",
        (SIM_REF,),
        "u_f: the synergetic term -spow(-phi1/T1) with its sign flipped",
    ),
    Mutant(
        "ur-law-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "- evolution(phi2, gains.T2, a, layer)",
        "+ evolution(phi2, gains.T2, a, layer)",
        (SIM_REF,),
        "u_r: the synergetic term -spow(-phi2/T2) with its sign flipped",
    ),
    Mutant(
        "uf-drift-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "b1 * f[0] + (c1 * x[1] + xdot2_hat)",
        "b1 * f[0] - (c1 * x[1] + xdot2_hat)",
        (SIM_REF,),
        "u_f: the x2 + xdot2_hat term with its sign flipped",
    ),
    Mutant(
        "th1-law-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "gains.gamma1 * (o1 + out.x[1] * s)",
        "gains.gamma1 * (o1 - out.x[1] * s)",
        (SIM_REF,),
        "adaptation of th1 (eq. 22): the phi term with its sign flipped",
    ),
    Mutant(
        "th2-law-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "gains.gamma2 * (o2 + s)",
        "gains.gamma2 * (o2 - s)",
        (SIM_REF,),
        "adaptation of th2 (eq. 22): the phi term with its sign flipped",
    ),
    Mutant(
        "k1-term-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "spow(-plant.D - th_hat[0], a)",
        "spow(th_hat[0] + plant.D, a)",
        (SIM_REF,),
        "adaptation of th1: the oracle pull k1 (theta1 - th1) with its sign flipped",
    ),
    Mutant(
        "k2-term-sign",
        "src/smibjax/controllers/synergetic/law.py",
        "spow(plant.Pm - th_hat[1], a)",
        "spow(th_hat[1] - plant.Pm, a)",
        (SIM_REF,),
        "adaptation of th2: the oracle pull k2 (theta2 - th2) with its sign flipped",
    ),
    # -- network stages (network.py) ------------------------------------------------
    Mutant(
        "stage-post-and-restored-swapped",
        "src/smibjax/_network.py",
        "jnp.where(in_fault, b, jnp.where(in_post, c, a))",
        "jnp.where(in_fault, b, jnp.where(in_post, a, c))",
        ("tests/test_network.py", SIM_REF),
        "post-fault and restored networks exchanged",
    ),
    Mutant(
        "stage-fault-until-reclose",
        "src/smibjax/_network.py",
        "in_fault = (t >= fault.t_fault) & (t < fault.t_clear)",
        "in_fault = (t >= fault.t_fault) & (t < fault.t_reclose)",
        ("tests/test_network.py", SIM_REF),
        "the fault is not cleared at t_clear (stays until t_reclose)",
    ),
    Mutant(
        "stage-post-never-ends",
        "src/smibjax/_network.py",
        "in_post = (t >= fault.t_clear) & (t < fault.t_reclose)",
        "in_post = t >= fault.t_clear",
        ("tests/test_network.py", SIM_REF),
        "the line is never reclosed",
    ),
    # -- losses.py ---------------------------------------------------------------------
    Mutant(
        "soft-settling-ignores-band",
        "src/smibjax/_losses.py",
        "s = jax.nn.sigmoid((remaining - band) / width) * after",
        "s = jax.nn.sigmoid(remaining / width) * after",
        ("tests/test_losses.py",),
        "soft settling time counts every sample after t_from, in the band or not",
    ),
    Mutant(
        "soft-settling-ignores-stop",
        "src/smibjax/_losses.py",
        "dev = jnp.where(t > t_stop, 10 * band, dev)",
        "dev = dev",
        ("tests/test_losses.py",),
        "a run that stopped (lost synchronism) could count as settled",
    ),
    Mutant(
        "overshoot-loss-from-zero",
        "src/smibjax/_losses.py",
        "z = jnp.where(traj.t >= traj.t_fault, dev / temperature, -jnp.inf)",
        "z = dev / temperature",
        ("tests/test_losses.py",),
        "soft overshoot also over the pre-fault samples (which sit at equilibrium: "
        "expected to change nothing measurable)",
    ),
    # -- metrics.py -------------------------------------------------------------------
    Mutant(
        "settling-no-interpolation",
        "src/smibjax/_metrics.py",
        "t_cross = t[i] + frac * (t[i + 1] - t[i])",
        "t_cross = t[i]",
        ("tests/test_metrics.py",),
        "exit from the band at the last sample outside, not interpolated",
    ),
    Mutant(
        "settling-ignores-t-from",
        "src/smibjax/_metrics.py",
        "outside = (dev > band) & (t >= t_from)",
        "outside = dev > band",
        ("tests/test_metrics.py",),
        "samples before fault inception count",
    ),
    Mutant(
        "settling-never-inf",
        "src/smibjax/_metrics.py",
        "return jnp.where(last == n - 1, jnp.inf, jnp.maximum(settled, 0.0))",
        "return jnp.maximum(settled, 0.0)",
        ("tests/test_metrics.py",),
        "a signal still outside its band at t_end reported as settled",
    ),
    Mutant(
        "stable-ignores-budget",
        "src/smibjax/_metrics.py",
        "traj.lost_sync | traj.budget_exhausted,",
        "traj.lost_sync,",
        ("tests/test_metrics.py::test_a_run_that_spent_its_step_budget_is_not_stable",),
        "a run that ran out of solver steps reported stable",
    ),
    Mutant(
        "overshoot-band-from-zero",
        "src/smibjax/_metrics.py",
        "return jnp.max(jnp.where(traj.t >= traj.t_fault, dev, 0.0))",
        "return jnp.max(dev)",
        ("tests/test_metrics.py",),
        "overshoot over the pre-fault samples too",
    ),
    # -- domain of the model (closed_loop.py) ---------------------------------------
    Mutant(
        "e-min-check-removed",
        "src/smibjax/_closed_loop.py",
        "        & (E > E_MIN)\n",
        "",
        (
            "tests/test_simulate.py::test_domain_thresholds_of_e_prime_and_transfer_reactance",
        ),
        "E' falling to 0 is not a loss of synchronism",
    ),
    Mutant(
        "reactance-threshold-fault-shunt-sign",
        "src/smibjax/_closed_loop.py",
        "return (xs - X_MIN) / (plant.X1 * stage.X2) - stage.Bf",
        "return (xs - X_MIN) / (plant.X1 * stage.X2) + stage.Bf",
        (
            "tests/test_simulate.py::test_domain_thresholds_of_e_prime_and_transfer_reactance",
        ),
        "the fault's shunt susceptance enters the reactance threshold with the wrong sign",
    ),
    Mutant(
        "reactance-check-removed",
        "src/smibjax/_closed_loop.py",
        "        & (B < b_lim)\n",
        "",
        (
            "tests/test_simulate.py::test_domain_thresholds_of_e_prime_and_transfer_reactance",
            "tests/test_simulate.py::test_loss_of_synchronism_through_the_reactance_threshold",
        ),
        "no transfer-reactance check: the run integrates through the singularity",
    ),
    # -- the batch engine (batch.py) and Monte Carlo run folders (cli/runs.py) ---------
    Mutant(
        "engine-structure-ignored",
        "src/smibjax/controllers/synergetic/controller.py",
        "        return (self.oracle, box, float(self.phi_layer))",
        "        return ()",
        ("tests/test_batch.py::test_structure_is_part_of_the_program",),
        "the engine's program key ignores the projection box: a second box reuses "
        "the first one compiled in",
    ),
    Mutant(
        "montecarlo-resume-recomputes-all",
        "src/smibjax/cli/runs.py",
        "    todo = [k for k in range(spec.n_chunks) if not _chunk_ok(out, spec, k)]",
        "    todo = list(range(spec.n_chunks))",
        ("tests/test_cluster.py::test_workers_end_to_end_finishes_an_interrupted_run",),
        "--resume recomputes every chunk (same rows: only the kept files and the "
        "count of computed scenarios tell)",
    ),
    Mutant(
        "one-slice-uncommitted",
        "src/smibjax/_parallel.py",
        "            out = single(jax.device_put(replicated, d), jax.device_put(batched, d))",
        "            out = single(replicated, batched)",
        (
            "tests/test_parallel.py::"
            "test_a_one_slice_batch_compiles_once_wherever_its_inputs_live",
        ),
        "a one-slice batch runs on uncommitted inputs: the tuner's second step "
        "compiles its program again",
    ),
    # -- atomic writes (_files.py)----------------------------------------------------------------
    Mutant(
        "io-write-in-place",
        "src/smibjax/_files.py",
        "        write(tmp)\n        os.chmod(tmp, file_mode())",
        "        write(str(p))\n        os.chmod(tmp, file_mode())",
        ("tests/test_io.py",),
        "the writer writes onto the target itself (a crash leaves half a file)",
    ),
    # -- the fixed-step scan (_fixed.py) ------------------------------------------------
    Mutant(
        "fixed-stage-at-step-end",
        "src/smibjax/_fixed.py",
        "0.5 * (ta_ + tb_),",
        "tb_,",
        ("tests/test_fixed.py",),
        "a step's network stage taken at its end, not its midpoint",
    ),
    Mutant(
        "fixed-no-hold-after-stop",
        "src/smibjax/_fixed.py",
        "y1 = jnp.where(alive, y1, y)\n",
        "\n",
        ("tests/test_fixed.py",),
        "steps after a loss of synchronism keep integrating",
    ),
    Mutant(
        "fixed-sample-off-by-one",
        "src/smibjax/_fixed.py",
        "samples = ys[index]",
        "samples = ys[jnp.minimum(index + 1, ys.shape[0] - 1)]",
        ("tests/test_fixed.py",),
        "each sample read one grid point late",
    ),
    Mutant(
        "fixed-switch-not-a-jump",
        "src/smibjax/_fixed.py",
        "jump = jnp.concatenate([is_switch[:-1], jnp.zeros(pad, bool)])",
        "jump = jnp.zeros(grid.shape[0] - 1 + pad, bool)",
        ("tests/test_fixed.py",),
        "Tsit5's FSAL state reused across a switch (made_jump never set)",
    ),
    # -- the power flow (grid/ybus.py, grid/powerflow.py) --
    Mutant(
        "pf-shift-sign",
        "src/smibjax/grid/ybus.py",
        "a = jnp.asarray(br.tap) * jnp.exp(1j * jnp.asarray(br.shift))",
        "a = jnp.asarray(br.tap) * jnp.exp(-1j * jnp.asarray(br.shift))",
        (
            PF
            + "test_ybus_equals_the_closed_form_with_a_tap_a_phase_shift_and_charging",
            PF + "test_a_transformer_divides_the_from_voltage_by_tap_e_j_shift",
        ),
        "the phase shift with the wrong sign (the to end leads)",
    ),
    Mutant(
        "pf-tap-on-to-side",
        "src/smibjax/grid/ybus.py",
        "    y_tt = y + half_b\n    y_ff = y_tt / jnp.asarray(br.tap) ** 2",
        "    y_ff = y + half_b\n    y_tt = y_ff / jnp.asarray(br.tap) ** 2",
        (
            PF
            + "test_ybus_equals_the_closed_form_with_a_tap_a_phase_shift_and_charging",
            PF + "test_a_transformer_divides_the_from_voltage_by_tap_e_j_shift",
        ),
        "the off-nominal tap on the to side",
    ),
    Mutant(
        "pf-branch-status-ignored",
        "src/smibjax/grid/ybus.py",
        "status = br.status if branch_status is None else branch_status",
        "status = br.status",
        (PF + "test_ybus_vmaps_over_branch_status_and_extra_shunts",),
        "ybus ignores its branch_status argument",
    ),
    Mutant(
        "pf-bus-shunt-ignored",
        "src/smibjax/grid/ybus.py",
        "diag = diag + bus_shunt",
        "diag = diag",
        (PF + "test_ybus_vmaps_over_branch_status_and_extra_shunts",),
        "ybus ignores its bus_shunt argument",
    ),
    Mutant(
        "pf-load-admittance-conj",
        "src/smibjax/grid/ybus.py",
        "y = (jnp.asarray(ld.p) - 1j * jnp.asarray(ld.q))",
        "y = (jnp.asarray(ld.p) + 1j * jnp.asarray(ld.q))",
        (PF + "test_load_admittance_draws_the_load_power_at_the_voltage",),
        "a load's admittance p + j q (draws -q)",
    ),
    Mutant(
        "pf-charging-not-halved",
        "src/smibjax/grid/ybus.py",
        "half_b = 0.5j * status",
        "half_b = 1.0j * status",
        (PF + "test_wscc9_matches_the_published_solution",),
        "the total charging b put at each end",
    ),
    Mutant(
        "pf-loads-low",
        "src/smibjax/grid/powerflow.py",
        "p_sched=p_gen - p_load,",
        "p_sched=p_gen - 0.99 * p_load,",
        (PF + "test_power_flow_equals_an_independent_rectangular_solver",),
        "the active loads scheduled 1% low",
    ),
    Mutant(
        "pf-pv-setpoint-from-bus",
        "src/smibjax/grid/powerflow.py",
        "v_set = jnp.where(has_gen, v_gen, jnp.asarray(b.vm))",
        "v_set = jnp.asarray(b.vm)",
        (PF + "test_power_flow_equals_an_independent_rectangular_solver",),
        "PV and slack buses hold the raw file's vm, not the generators' v_set",
    ),
    Mutant(
        "pf-newton-loose",
        "src/smibjax/grid/powerflow.py",
        "rtol=tol, atol=tol, linear_solver",
        "rtol=1e-2, atol=1e-2, linear_solver",
        (PF + "test_the_solution_satisfies_the_power_flow_equations",),
        "Newton stops at a 1e-2 mismatch",
    ),
    Mutant(
        "pf-dq-at-pv",
        "src/smibjax/grid/powerflow.py",
        "dq = jnp.where(s.fixed_v, 0.0, jnp.imag(inj) - s.q_sched)",
        "dq = jnp.where(s.slack, 0.0, jnp.imag(inj) - s.q_sched)",
        (PF + "test_the_solution_satisfies_the_power_flow_equations",),
        "Q mismatches reported at PV buses, where Q is free",
    ),
    Mutant(
        "pf-q-shared-equally",
        "src/smibjax/grid/powerflow.py",
        "q_shared = q_case + jnp.where(ok_rest[gbus], rest_rng, rest_eq)",
        "q_shared = q_case + rest_eq",
        (PF + "test_generators_share_their_bus",),
        "a bus's Q shared equally, not by the generators' ranges",
    ),
    Mutant(
        "pf-q-ignores-case-q",
        "src/smibjax/grid/powerflow.py",
        "q_case = on * jnp.asarray(g.q)",
        "q_case = 0.0 * jnp.asarray(g.q)",
        (PF + "test_generators_on_one_bus_keep_the_case_q",),
        "machines on one bus re-shared by range, the case's own q ignored",
    ),
    Mutant(
        "pf-flat-is-case",
        "src/smibjax/grid/powerflow.py",
        'flat = jnp.asarray(start == "flat")',
        "flat = jnp.asarray(False)",
        (PF + "test_a_flat_start_ignores_the_raw_file_voltages",),
        "start='flat' starts from the raw file",
    ),
    Mutant(
        "pf-loads-no-derivative",
        "src/smibjax/grid/powerflow.py",
        "p_load = _bus_sum(n, lbus, jnp.asarray(ld.p))",
        "p_load = jax.lax.stop_gradient(_bus_sum(n, lbus, jnp.asarray(ld.p)))",
        (PF + "test_gradients_with_respect_to_the_loads_equal_finite_differences",),
        "the loads held out of the derivative",
    ),
    Mutant(
        "pf-network-no-derivative",
        "src/smibjax/grid/powerflow.py",
        "    Y, s = args\n",
        "    Y, s = args\n    Y = jax.lax.stop_gradient(Y)\n",
        (PF + "test_reverse_mode_gradients_in_network_and_generation_parameters",),
        "the network held out of the derivative",
    ),
    Mutant(
        "pf-load-q-not-scaled",
        "src/smibjax/grid/powerflow.py",
        "            jnp.asarray(ld.q) * load_factor,",
        "            jnp.asarray(ld.q),",
        (PF + "test_vmap_over_load_factors_equals_the_loop_with_one_compile",),
        "scale_operating_point leaves the reactive loads",
    ),
    Mutant(
        "pf-factors-on-host",
        "src/smibjax/grid/powerflow.py",
        "            jnp.asarray(ld.p) * load_factor,",
        "            jnp.asarray(ld.p) * float(load_factor),",
        (PF + "test_vmap_over_load_factors_equals_the_loop_with_one_compile",),
        "the load factor read on the host (not traceable, no batch)",
    ),
    Mutant(
        "pf-outage-ignored",
        "src/smibjax/grid/powerflow.py",
        "    Y = ybus(system, branch_status)",
        "    Y = ybus(system)",
        (PF + "test_vmap_over_branch_outages_equals_the_loop",),
        "power_flow ignores branch_status",
    ),
    Mutant(
        "pf-error-names-position",
        "src/smibjax/grid/powerflow.py",
        "mismatch_bus=jnp.asarray(system.buses.number)[worst % n],",
        "mismatch_bus=worst % n,",
        (PF + "test_beyond_the_nose_the_error_names_the_worst_bus",),
        "the error names the bus position, not its number",
    ),
    Mutant(
        "pf-no-slack-check",
        "src/smibjax/grid/powerflow.py",
        "    if not np.any(kind == SLACK):",
        "    if False:",
        (PF + "test_bad_input_is_one_line",),
        "a system without a slack bus goes to Newton",
    ),
    # -- the PSS/E reader (grid/psse.py) ---------------------------------------------
    Mutant(
        "psse-no-t2-squared",
        PSSE,
        'z = _impedance(r, "1-2", sbase, where) * t2 * t2',
        'z = _impedance(r, "1-2", sbase, where)',
        (
            f"{PSSE_T}::test_transformer_cw1_cz1_cm1",
            f"{PSSE_T}::test_transformer_cw2_cz2",
        ),
        "the transformer impedance not moved through t2 with the ratio (ANDES's way)",
    ),
    Mutant(
        "psse-cw2-no-base-kv",
        PSSE,
        "        return windv / vb\n",
        "        return windv\n",
        (f"{PSSE_T}::test_transformer_cw2_cz2",),
        "CW = 2 winding voltages taken as per-unit ratios",
    ),
    Mutant(
        "psse-cw3-no-nomv",
        PSSE,
        'return windv * (r["NOMV" + w] or vb) / vb',
        "return windv",
        (
            f"{PSSE_T}::test_transformer_cw3_cz3_cm2",
            f"{PSSE_T}::test_three_winding_transformers",
        ),
        "CW = 3 ratios not scaled by NOMV / BASKV",
    ),
    Mutant(
        "psse-cz3-loss-base",
        PSSE,
        "rw = rr / (1e6 * s_w)",
        "rw = rr / 1e6",
        (f"{PSSE_T}::test_transformer_cw3_cz3_cm2",),
        "CZ = 3 load loss not divided by the winding MVA base",
    ),
    Mutant(
        "psse-cm2-b-sign",
        PSSE,
        "return complex(g, -math.sqrt(y * y - g * g))",
        "return complex(g, math.sqrt(y * y - g * g))",
        (f"{PSSE_T}::test_transformer_cw3_cz3_cm2",),
        "CM = 2 magnetizing susceptance capacitive (ANDES's sign)",
    ),
    Mutant(
        "psse-shift-in-degrees",
        PSSE,
        'return z.real, z.imag, t1 / t2, math.radians(r["ANG1"]), y_m',
        'return z.real, z.imag, t1 / t2, r["ANG1"], y_m',
        (f"{PSSE_T}::test_phase_shifter_and_out_of_service_transformer",),
        "ANG1 left in degrees",
    ),
    Mutant(
        "psse-star-legs-swapped",
        PSSE,
        "zs = ((z12 + z31 - z23) / 2, (z12 + z23 - z31) / 2, (z23 + z31 - z12) / 2)",
        "zs = ((z12 + z23 - z31) / 2, (z12 + z31 - z23) / 2, (z23 + z31 - z12) / 2)",
        (f"{PSSE_T}::test_three_winding_transformers",),
        "the star impedances of windings 1 and 2 exchanged",
    ),
    Mutant(
        "psse-line-end-shunts-dropped",
        PSSE,
        '            shunt(r["I"], r["GI"], r["BI"])\n',
        "            pass\n",
        (f"{PSSE_T}::test_shunts",),
        "a branch's GI + jBI not placed at bus I",
    ),
    Mutant(
        "psse-genrou-order",
        PSSE,
        '    "GENROU": (\n        "Tdo_p",\n        "Tdo_pp",',
        '    "GENROU": (\n        "Tdo_pp",\n        "Tdo_p",',
        (f"{PSSE_T}::test_read_dyr", f"{PSSE_T}::test_dyr_order_against_andes_yaml"),
        "GENROU's T'do and T''do read in each other's place",
    ),
    Mutant(
        "psse-no-machine-check",
        PSSE,
        "if float(np.asarray(gens.status)[g]) != 0.0 and",
        "if False and",
        (f"{PSSE_T}::test_check_dynamics_errors",),
        "a generator in service without a machine record accepted",
    ),
    # -- grid controller models ---------------------------------------------------
    Mutant(
        "controls-equilibrium-sexs",
        "src/smibjax/grid/devices/sexs.py",
        'ref = regulated(meas) - meas["Vs"] + y0 / self.K',
        "ref = regulated(meas) + y0 / self.K",
        (f"{CONTROLS}::test_init_is_an_equilibrium",),
        "SEXS's Vref without the stabilizer's rest value: init is not at rest",
    ),
    Mutant(
        "controls-leadlag-ratio",
        "src/smibjax/grid/devices/_blocks.py",
        "x + T_lead / _safe(T_lag) * (u - x)",
        "x + 0.5 * T_lead / _safe(T_lag) * (u - x)",
        (
            f"{CONTROLS}::test_sexs_step_response_is_the_leadlag_lag_closed_form",
            f"{CONTROLS}::test_tgov1_lag_and_leadlag_step_responses_and_static_gain",
        ),
        "a lead-lag's high-frequency gain halved",
    ),
    Mutant(
        "controls-tgov1-dt",
        "src/smibjax/grid/devices/tgov1.py",
        "return yt - self.Dt * w,",
        "return yt,",
        (f"{CONTROLS}::test_tgov1_lag_and_leadlag_step_responses_and_static_gain",),
        "TGOV1's turbine damping Dt dropped",
    ),
    Mutant(
        "controls-washout-gain",
        "src/smibjax/grid/devices/stab1.py",
        "y_w = self.K_T * (u - x[0])",
        "y_w = self.K_T * (u - 0.9 * x[0])",
        (f"{CONTROLS}::test_stab1_washout_step_response",),
        "a washout whose state is weighted 0.9: it no longer washes out",
    ),
    Mutant(
        "controls-2nd-order-lag",
        "src/smibjax/grid/devices/_blocks.py",
        "dx2 = jnp.where(second, (u - x1 - a1 * x2) / _safe(a2), 0.0)",
        "dx2 = jnp.where(second, (u - x1 - a2 * x2) / _safe(a1), 0.0)",
        (f"{CONTROLS}::test_ieeest_frequency_response_is_its_transfer_function",),
        "the second-order lag's a1 and a2 swapped",
    ),
    Mutant(
        "controls-nonwindup",
        "src/smibjax/grid/devices/_blocks.py",
        "return jnp.where(pinned, 0.0, dx)",
        "return dx",
        (
            f"{CONTROLS}::test_sexs_limit_holds_the_state_and_releases_within_one_time_constant",
            f"{CONTROLS}::test_exst1_limit_holds_the_state_and_releases_within_one_time_constant",
            f"{CONTROLS}::test_tgov1_valve_limit_holds_the_state_and_releases_within_one_time_constant",
        ),
        "non-windup limits that let the state wind up",
    ),
    Mutant(
        "controls-saturation-a",
        "src/smibjax/grid/devices/ieeex1.py",
        "A = jnp.where(on, E2 - d / am1, 0.0)",
        "A = jnp.where(on, E2 + d / am1, 0.0)",
        (
            f"{CONTROLS}::test_ieeex1_saturation_fit_passes_through_both_points",
            f"{CONTROLS}::test_ieeex1_saturation_kundur_numbers_and_no_data",
        ),
        "the quadratic saturation's A with the wrong sign",
    ),
    Mutant(
        "controls-csvgn1-cmd-sign",
        "src/smibjax/grid/devices/csvgn1.py",
        "ref[1] + y2 - cmd",
        "ref[1] + y2 + cmd",
        (f"{CONTROLS}::test_csvgn1_reduces_to_the_paper_svc",),
        "CSVGN1's external command with the wrong sign",
    ),
    Mutant(
        "controls-ieeex1-feedback",
        "src/smibjax/grid/devices/ieeex1.py",
        "vf, dxf = washout(x[4], x[3], self.KF, self.TF1)",
        "vf, dxf = washout(x[4], x[3], 0.5 * self.KF, self.TF1)",
        (f"{CONTROLS}::test_ieeex1_against_andes",),
        "IEEEX1's rate feedback gain halved",
    ),
    Mutant(
        "controls-tgov1-lead-lag",
        "src/smibjax/grid/devices/tgov1.py",
        "yt, dt = leadlag(x[1], xv, self.T2, self.T3)",
        "yt, dt = leadlag(x[1], xv, self.T3 * 0.1, self.T3)",
        (f"{CONTROLS}::test_tgov1_against_andes",),
        "TGOV1's turbine lead T2 replaced by T3/10",
    ),
    Mutant(
        "controls-ieeest-washout",
        "src/smibjax/grid/devices/ieeest.py",
        "yw, d7 = washout(x[6], self.KS * y4, self.T5, self.T6)",
        "yw, d7 = washout(x[6], self.KS * y4, self.T5, 1.1 * self.T6)",
        (f"{CONTROLS}::test_ieeest_against_andes",),
        "IEEEST's washout lag T6 10% long",
    ),
    Mutant(
        "controls-exst1-vs-sign",
        "src/smibjax/grid/devices/exst1.py",
        'vi = jnp.clip(ref - vm - vf + meas["Vs"]',
        'vi = jnp.clip(ref - vm - vf - meas["Vs"]',
        (f"{CONTROLS}::test_exst1_special_case_is_the_smib_st1a_exciter",),
        "EXST1's stabilizer signal subtracted",
    ),
    Mutant(
        "controls-ieeest-cutoff",
        "src/smibjax/grid/devices/ieeest.py",
        "(vt < self.VCU)",
        "(vt <= 99.0)",
        (f"{CONTROLS}::test_output_limiters_and_cutoff",),
        "IEEEST's upper voltage cutoff ignored",
    ),
    Mutant(
        "controls-ke-0-rule",
        "src/smibjax/grid/devices/ieeex1.py",
        "ke = jnp.where(self.KE == 0, -self.se(y0), self.KE)",
        "ke = self.KE",
        (f"{CONTROLS}::test_ieeex1_self_excited_field_rests_at_zero_regulator_output",),
        "KE = 0 taken as given (no self-excited field rule)",
    ),
    Mutant(
        "controls-directfield",
        "src/smibjax/grid/devices/direct.py",
        'jnp.clip(ref + meas["Efd_cmd"]',
        'jnp.clip(ref + 0.0 * meas["Efd_cmd"]',
        (f"{CONTROLS}::test_direct_field_holds_efd0_plus_the_command",),
        "DirectField ignores its command",
    ),
    Mutant(
        "controls-guarded-divisor",
        "src/smibjax/grid/devices/_blocks.py",
        "return jnp.where(T > 0, T, 1.0)",
        "return T",
        (f"{CONTROLS}::test_gradients_are_finite_across_zero_time_constants",),
        "a zero time constant divides unguarded: NaN gradients",
    ),
    Mutant(
        "controls-missing-key-msg",
        "src/smibjax/grid/devices/_blocks.py",
        'f"{cls.__name__} record {i} (position {positions[i]}) has no {n}"',
        'f"{cls.__name__} record {i} lacks {n}"',
        (f"{CONTROLS}::test_bad_records_are_refused_in_one_line",),
        "a missing dyr CON reported without the record's position",
    ),
    # -- governors and stabilizers of issue 45 (tests/test_grid_govpss.py) ------------
    Mutant(
        "govpss-ieeest-no-swap",
        "src/smibjax/grid/devices/ieeest.py",
        "    keep = d2 >= n\n",
        "    keep = d2 >= 0\n",
        (
            f"{GOVPSS}::test_ieeest_full_filter_with_a3_a4_zero_is_its_transfer_function",
        ),
        "IEEEST's numerator always over (A3, A4): A3 = A4 = 0 with A6 != 0 wrong",
    ),
    Mutant(
        "govpss-ieeeg1-k7",
        "src/smibjax/grid/devices/ieeeg1.py",
        " + self.K7 * y7\n",
        "\n",
        (f"{GOVPSS}::test_ieeeg1_transfer_function",),
        "IEEEG1 without its fourth stage's HP share",
    ),
    Mutant(
        "govpss-ieeeg1-no-rate-limit",
        "src/smibjax/grid/devices/ieeeg1.py",
        "rate = jnp.clip((ref - y_ll - gv) / self.T3, self.UC, self.UO)",
        "rate = (ref - y_ll - gv) / self.T3",
        (f"{GOVPSS}::test_ieeeg1_valve_rate_and_position_limits",),
        "IEEEG1's valve rate limits UO, UC dropped",
    ),
    Mutant(
        "govpss-hygov-pi",
        "src/smibjax/grid/devices/hygov.py",
        "(e + self.Tr * de)",
        "(e + de)",
        (f"{GOVPSS}::test_hygov_transfer_function_is_the_linearized_water_column",),
        "HYGOV's governor zero (1 + s Tr) lost",
    ),
    Mutant(
        "govpss-hygov-velm",
        "src/smibjax/grid/devices/hygov.py",
        "-self.VELM, self.VELM)",
        "-10 * self.VELM, self.VELM)",
        (f"{GOVPSS}::test_hygov_gate_velocity_limit",),
        "HYGOV's closing velocity limit ten times too loose",
    ),
    Mutant(
        "govpss-hygov-servo",
        "src/smibjax/grid/devices/hygov.py",
        "_, dg = lag(g, c, 1.0, self.Tg)",
        "_, dg = lag(g, c, 1.0, 2 * self.Tg)",
        (f"{GOVPSS}::test_governor_against_andes",),
        "HYGOV's gate servo twice as slow (ANDES's run catches it)",
    ),
    Mutant(
        "govpss-ieesgo-k3",
        "src/smibjax/grid/devices/ieesgo.py",
        "(1.0 - self.K3) * y5",
        "(1.0 - self.K2) * y5",
        (f"{GOVPSS}::test_ieesgo_transfer_function",),
        "IEESGO's reheater share taken with the wrong fraction",
    ),
    Mutant(
        "govpss-ieesgo-init",
        "src/smibjax/grid/devices/ieesgo.py",
        "x5 = self.K2 * y0",
        "x5 = y0",
        (f"{GOVPSS}::test_kundur_with_every_new_model_starts_at_an_exact_equilibrium",),
        "IEESGO's reheater state initialized off its rest value",
    ),
    Mutant(
        "govpss-gast-gate",
        "src/smibjax/grid/devices/gast.py",
        "jnp.minimum(u_s, u_l)",
        "jnp.maximum(jnp.minimum(u_s, u_l), u_s)",
        (f"{GOVPSS}::test_gast_load_limit_takes_over",),
        "GAST's low-value gate ignores the load limit",
    ),
    Mutant(
        "govpss-gast-measurement",
        "src/smibjax/grid/devices/gast.py",
        "self.AT + self.KT * (self.AT - x[2])",
        "self.AT + self.KT * (self.AT - x[1])",
        (f"{GOVPSS}::test_gast_load_limit_takes_over",),
        "GAST's load limit without its exhaust-temperature lag T3",
    ),
    Mutant(
        "govpss-st2cut-signal",
        "src/smibjax/grid/devices/st2cut.py",
        'jnp.where(ics == 3, meas["Pe"]',
        'jnp.where(ics == 3, meas["omega"]',
        (f"{GOVPSS}::test_st2cut_transfer_functions_of_both_inputs",),
        "ST2CUT's code 3 reads speed instead of electrical power",
    ),
    Mutant(
        "govpss-st2cut-leadlag",
        "src/smibjax/grid/devices/st2cut.py",
        "leadlag(x[3], yw, self.T5, self.T6)",
        "leadlag(x[3], yw, self.T6, self.T5)",
        (f"{GOVPSS}::test_st2cut_against_andes",),
        "ST2CUT's first lead-lag inverted (ANDES's run catches it)",
    ),
    Mutant(
        "govpss-stab2a-sign",
        "src/smibjax/grid/devices/stab2a.py",
        "washout(x[0], -u, k, self.T2)",
        "washout(x[0], u, k, self.T2)",
        (f"{GOVPSS}::test_stab2a_transfer_function",),
        "STAB2A's first washout not negated",
    ),
    Mutant(
        "govpss-pss2-channel-2",
        "src/smibjax/grid/devices/pss2.py",
        "self.KS1 * (z - y2)",
        "self.KS1 * (z + y2)",
        (f"{GOVPSS}::test_pss2_transfer_functions_of_both_channels",),
        "PSS2A/B add channel 2 after the ramp-tracking filter instead of subtracting it",
    ),
    Mutant(
        "govpss-pss2-ramp-filter",
        "src/smibjax/grid/devices/pss2.py",
        "lead = jnp.where(j % Ms == 0, T8, 0.0)",
        "lead = jnp.where(j % Ms == 1, T8, 0.0)",
        (f"{GOVPSS}::test_pss2_transfer_functions_of_both_channels",),
        "the ramp-tracking filter's lead T8 on the wrong block of each stage",
    ),
    Mutant(
        "govpss-pss2b-input-limit",
        "src/smibjax/grid/devices/pss2.py",
        "jnp.clip(u1, self.VS1MIN, self.VS1MAX)",
        "u1",
        (f"{GOVPSS}::test_pss2b_input_limits_clip_the_signal",),
        "PSS2B's input limits on channel 1 dropped",
    ),
    Mutant(
        "govpss-pss2-init",
        "src/smibjax/grid/devices/pss2.py",
        "x0 = [u1, zero, zero, u2]",
        "x0 = [u1, zero, zero, zero]",
        (f"{GOVPSS}::test_kundur_with_every_new_model_starts_at_an_exact_equilibrium",),
        "PSS2B's second channel washout not at its input at rest",
    ),
    Mutant(
        "govpss-gradient",
        "src/smibjax/grid/devices/ieeeg1.py",
        "y_ll, d_ll = leadlag(x[0], self.K * w, self.T2, self.T1)",
        "y_ll, d_ll = leadlag(x[0], __import__('jax').lax.stop_gradient(self.K) * w, "
        "self.T2, self.T1)",
        (f"{GOVPSS}::test_gradients_match_central_differences",),
        "IEEEG1's gain cut from the derivative",
    ),
    Mutant(
        "govpss-ieeest-improper-rule",
        "src/smibjax/grid/devices/ieeest.py",
        '    (\n        "A6",',
        '    (\n        "A4",',
        (f"{GOVPSS}::test_ieeest_refuses_only_an_improper_filter",),
        "IEEEST's improper-filter refusal names the wrong parameter",
    ),
    Mutant(
        "govpss-hygov-tf-check",
        "src/smibjax/grid/devices/hygov.py",
        '*positive("r", "Tr", "Tf", "Tg", "TW", "At")',
        '*positive("r", "Tr", "Tg", "TW", "At")',
        (f"{GOVPSS}::test_bad_parameters_are_refused_in_one_line",),
        "HYGOV accepts Tf = 0 (its governor divides by it)",
    ),
]

# issue 47: loads as PSS/E models them, the Newton network, load and reference steps
LOADS = "tests/test_grid_loads.py"
MUTANTS += [
    Mutant(
        "loads-newton-drops-injection",
        "src/smibjax/grid/network.py",
        "    return v_lin + W @ i_j, vj, res",
        "    return v_lin, vj, res",
        (f"{LOADS}::test_newton_solves_the_whole_network",),
        "the port voltages leave out the injectors' currents",
    ),
    Mutant(
        "loads-collapse-never",
        "src/smibjax/grid/network.py",
        "COLLAPSE_TOL = 1e-6",
        "COLLAPSE_TOL = 1e9",
        (f"{LOADS}::test_collapse_is_a_result",),
        "a network with no solution runs on",
    ),
    Mutant(
        "loads-gradient-stops-at-newton",
        "src/smibjax/grid/network.py",
        "    i_j = current(vj)\n",
        "    i_j = current(jax.lax.stop_gradient(vj))\n",
        (f"{LOADS}::test_gradient_through_the_newton_solve",),
        "the derivative ignores how the solved voltages move",
    ),
    Mutant(
        "loads-kp-kink",
        "src/smibjax/grid/devices/zipload.py",
        "1 - 2 * (x - 1) ** 2",
        "1 - (x - 1) ** 2",
        (f"{LOADS}::test_low_voltage_characteristics",),
        "PQBRAK's characteristic jumps at PQBRAK/2",
    ),
    Mutant(
        "loads-constant-power-as-impedance",
        "src/smibjax/grid/devices/zipload.py",
        "jnp.conj(ref[0]) * kp / m",
        "jnp.conj(ref[0]) * kp * m",
        (f"{LOADS}::test_against_psse[constant-power]",),
        "constant power loads draw a current that grows with the voltage",
    ),
    Mutant(
        "loads-andes-shares-swapped",
        "src/smibjax/grid/loads.py",
        "rows += [a * rest, b * rest + f_i, c * rest]",
        "rows += [c * rest, b * rest + f_i, a * rest]",
        (f"{LOADS}::test_against_andes_zip_loads",),
        "the constant power and impedance shares are swapped",
    ),
    Mutant(
        "loads-step-scale-ignored",
        "src/smibjax/grid/loop.py",
        "                else scale[np.asarray(lay.injector_src[k], dtype=np.int64)]",
        "                else jnp.ones(len(lay.injector_src[k]))",
        (f"{LOADS}::test_load_step_scales_every_part[zip]",),
        "a load step leaves the constant power and current parts alone",
    ),
    Mutant(
        "loads-step-shunt-missing",
        "src/smibjax/grid/network.py",
        "cfg.fault_y.at[bus].add(e.delta * grid.load_y[e.load]),",
        "cfg.fault_y,",
        (f"{LOADS}::test_load_step_scales_every_part[impedance]",),
        "a load step leaves the impedance part alone",
    ),
    Mutant(
        "loads-vref-step-ignored",
        "src/smibjax/grid/loop.py",
        "            vs = vs + mats.vref_add[stage][g]",
        "            vs = vs",
        (f"{LOADS}::test_reference_steps",),
        "a Vref step does not reach the exciter",
    ),
]


def _copy(dst: Path) -> None:
    ignore = shutil.ignore_patterns(
        ".git",
        ".jax_cache",
        "__pycache__",
        ".pytest_cache",
        ".ruff_cache",
        "*.egg-info",
        "runs",
        "results",
        ".venv",
    )
    shutil.copytree(ROOT, dst, ignore=ignore, symlinks=True)


def run_one(m: Mutant, cache: Path, timeout: float, verbose: bool) -> dict:
    with tempfile.TemporaryDirectory(prefix=f"smibjax-mutant-{m.name}-") as tmp:
        copy = Path(tmp) / "repo"
        _copy(copy)
        target = copy / m.file
        text = target.read_text()
        count = text.count(m.old)
        if count != 1:
            return {"status": "stale", "detail": f"old text found {count} times"}
        target.write_text(text.replace(m.old, m.new))
        (copy / ".jax_cache").symlink_to(cache, target_is_directory=True)
        env = {
            **os.environ,
            "PYTHONPATH": f"{copy / 'src'}{os.pathsep}{copy}",
            "SMIBJAX_CACHE_DIR": str(cache),
            "JAX_PLATFORMS": "cpu",
            "MPLBACKEND": "Agg",
        }
        where = subprocess.run(
            [sys.executable, "-c", "import smibjax; print(smibjax.__file__)"],
            env=env,
            cwd=copy,
            capture_output=True,
            text=True,
        ).stdout.strip()
        if not where.startswith(str(copy)):
            return {"status": "error", "detail": f"smibjax imported from {where}"}
        cmd = [
            sys.executable,
            "-m",
            "pytest",
            "-x",
            "-q",
            "-p",
            "no:cacheprovider",
            "-n",
            "0",
        ]
        t0 = time.perf_counter()
        try:
            p = subprocess.run(
                [*cmd, *m.select],
                env=env,
                cwd=copy,
                capture_output=True,
                text=True,
                timeout=timeout,
            )
        except subprocess.TimeoutExpired:
            return {"status": "timeout", "seconds": time.perf_counter() - t0}
        seconds = time.perf_counter() - t0
        status = {0: "survived", 1: "killed"}.get(p.returncode, "error")
        failed = [ln for ln in p.stdout.splitlines() if ln.startswith("FAILED")]
        if verbose or status == "error":
            print(p.stdout[-3000:], p.stderr[-2000:], sep="\n", file=sys.stderr)
        return {
            "status": status,
            "returncode": p.returncode,
            "seconds": round(seconds, 1),
            "failed": [ln.split(" - ")[0].removeprefix("FAILED ") for ln in failed],
            "summary": (p.stdout.strip().splitlines() or [""])[-1],
        }


def _save(out: Path, results: dict) -> None:
    """Merge into the JSON of earlier runs (a run of some mutants keeps the others')."""
    old = json.loads(out.read_text()) if out.is_file() else {}
    names = {m.name for m in MUTANTS}
    merged = {k: v for k, v in {**old, **results}.items() if k in names}
    out.write_text(json.dumps(merged, indent=1) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", metavar="NAME", help="names or patterns")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--json", default=str(ROOT / "tests" / "mutations.json"))
    ap.add_argument("--timeout", type=float, default=1800.0, help="s per mutant")
    ap.add_argument("-v", "--verbose", action="store_true", help="show pytest output")
    args = ap.parse_args(argv)
    chosen = [
        m
        for m in MUTANTS
        if not args.only or any(fnmatch.fnmatch(m.name, p) for p in args.only)
    ]
    if args.list or not chosen:
        for m in MUTANTS:
            print(f"{m.name:34} {m.file:28} {' '.join(m.select)}")
        return 0 if chosen or args.list else 2
    cache = Path(tempfile.gettempdir()) / "smibjax-mutants-cache"
    cache.mkdir(exist_ok=True)
    results = {}
    for m in chosen:
        print(f"{m.name} ...", end="", flush=True, file=sys.stderr)
        r = run_one(m, cache, args.timeout, args.verbose)
        print(f" {r['status']} ({r.get('seconds', 0)} s)", file=sys.stderr)
        results[m.name] = {**r, "file": m.file, "select": list(m.select), "why": m.why}
        _save(Path(args.json), results)  # after each mutant: a long run can be cut
    print("\n| mutant | file | result | failing test |\n|---|---|---|---|")
    for name, r in results.items():
        first = (r.get("failed") or ["-"])[0]
        print(f"| {name} | {r['file']} | {r['status']} | {first} |")
    killed = sum(r["status"] == "killed" for r in results.values())
    print(f"\n{len(results)} mutants, {killed} killed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
