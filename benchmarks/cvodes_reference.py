"""SUNDIALS CVODES (BDF) reference of jaxclear's smooth clearance-joint slider-crank (CasADi).

What it is: a CasADi SX port of the smooth-mode vector field dy/dt = f(t, y) of the independent
NumPy/SciPy reference ``tests/reference/scipy_slider_crank.py`` (``mode="smooth"``,
``smoothing_variant="jaxclear"``, jaxclear's default Baumgarte gains), which is the same model as
jaxclear's smooth model.  State y = (q[9], qd[9], m[n_clearance] impact-velocity memories,
z[n_clearance] LuGre states with LuGre friction).  Every formula and smoothing of the reference is
kept (C1 ramps, clamps and floors become ``casadi.if_else``/``fmin``/``fmax``); the multipliers
come from the same Schur complement, solved with ``casadi.solve``.  Only the parameter values
(Hertz stiffness per joint, geometry, masses, initial state) are read from the reference class;
jaxclear itself is imported only for its default Baumgarte gains (50, 50 if it is not importable).
It lets a benchmark time CVODES in the same run (and on the same machine) as jaxclear instead of
quoting old figures.

Install (optional, benchmark only, not a project dependency)::

    pip install casadi          # tested with casadi 3.8.2 (SUNDIALS CVODES bundled)

Cases (as in benchmarks/bench_clearance.py): 5000 rpm, c = 0.5 mm, Lankarani-Nikravesh c_e = 0.9,
no gravity, 2 revolutions, 721 output points (360 per revolution, t = 0 included):
    a  clearance joint B only, modified Coulomb mu = 0.01;
    b  clearance joints O, A, B, modified Coulomb mu = 0.01;
    c  clearance joints O, A, B, LuGre (defaults).

Commands::

    python benchmarks/cvodes_reference.py --check              # port vs SciPy reference
    python benchmarks/cvodes_reference.py [--cases a,b,c] [--repeats 3] [--jit] [--json]

``--check``: per case, the right-hand side against ``SliderCrank.evaluate`` at the initial state
and at 20 states of a SciPy Radau solve of the first 2 ms (contact and free flight): max relative
difference |f_casadi - f_ref| / |f_ref| over the components with |f_ref| >= 1e-6 of the scale of
their block (q', q'', m', z'; max |f_ref| over the states), and max |f_casadi - f_ref| / scale over
all components (a component that vanishes by cancellation, e.g. a zero y-acceleration computed as
3e-30, is rounding noise relative to its block's scale); the AD Jacobian is finite at all states
(e = 0 at the start); the compiled C of ``--jit`` equals the SX functions; then a CVODES solution
of the first 1 ms (rtol 1e-10) against SciPy DOP853 (rtol 1e-10): max difference of the slider x
and of the journal eccentricity vectors (µm).
Timing (default): ``casadi.integrator("F", "cvodes", ...)`` on the 721-point grid, rtol 1e-6,
atol 1e-9, BDF, Newton, exact (CasADi AD) Jacobian, max_num_steps 1e6; the integrator call alone
is timed (median of ``--repeats`` after one warm-up call; construction excluded).  Prints the
CVODES counters of ``F.stats()`` (steps, RHS evaluations, linear-solver setups = Jacobian
evaluations, Newton iterations, error-test failures) and the cycle statistics that compare with
jaxclear's: RMS slider acceleration and RMS crank torque over the second revolution (361 grid
points), peak normal force per clearance joint over the whole grid.  ``--json`` prints one JSON
line per case (the dict of ``cvodes_run``) for a parent process; ``cvodes_run(case, repeats, jit)``
can also be imported and called in-process.

Caveats:
* the model is the same as jaxclear's smooth model as far as ``--check`` shows (right-hand side at
  rounding level against the SciPy reference, which the test suite compares with jaxclear); over two
  revolutions solutions of this chaotic impact system do not agree pointwise between solvers
  (docs/model.md §5b), hence the cycle statistics;
* without ``--jit`` the right-hand side and its Jacobian run in CasADi's SX virtual machine
  (an interpreted instruction list); ``--jit`` generates C for both with CasADi's CodeGenerator,
  compiles it with the system C compiler ($CC, default ``gcc -O3 -shared -fPIC``) and loads it
  with ``casadi.external`` (the integrator options {"jit": True, "compiler": "shell"} do not work
  for CVODES in casadi 3.8: through common/specific_options they reach CasADi's internal Jacobian
  helper, which rejects them).  The C compile time is reported (``compile_s``), not in run_s.
  ``--check`` shows the compiled f and Jacobian equal to the SX ones; both variants take the same
  steps.  The old issue figures (0.10/0.15/0.12 s) were for a compiled C right-hand side;
* CVODES' step-size and order heuristics differ from jaxclear's solvers: compare run times and
  statistics, not step counts one to one.
"""

import argparse
import atexit
import functools
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

RPM = 5000.0
CLEARANCE = 5e-4
RESTITUTION = 0.9
REVOLUTIONS = 2
POINTS_PER_REVOLUTION = 360
RTOL, ATOL = 1e-6, 1e-9
MAX_NUM_STEPS = 1_000_000
CASES = {
    "a": dict(joints="B", friction=("modified-coulomb", 0.01), label="1 joint B, mod. Coulomb"),
    "b": dict(joints="OAB", friction=("modified-coulomb", 0.01), label="3 joints, mod. Coulomb"),
    "c": dict(joints="OAB", friction=("lugre",), label="3 joints OAB, LuGre (defaults)"),
}


@functools.cache
def baumgarte_gains():
    """jaxclear's default Baumgarte (alpha, beta), as bench_clearance.py passes them to the
    reference; (50, 50), the documented default, when jaxclear is not importable."""
    try:
        from jaxclear.mechanisms import slider_crank
    except ImportError:
        return 50.0, 50.0
    mech = slider_crank()
    return float(mech.baumgarte_alpha), float(mech.baumgarte_beta)


def _reference():
    path = os.path.join(REPO, "tests")
    if path not in sys.path:
        sys.path.insert(0, path)
    from reference import scipy_slider_crank

    return scipy_slider_crank


def reference_model(case, gains=None):
    """The SciPy reference ``SliderCrank`` of a case, built as bench_clearance's scipy_worker
    builds it (smooth mode, jaxclear smoothing variant, jaxclear's Baumgarte gains)."""
    ref = _reference()
    alpha, beta = gains or baumgarte_gains()
    spec = CASES[case]
    return ref.SliderCrank(
        tuple(spec["joints"]),
        RPM,
        "smooth",
        RESTITUTION,
        spec["friction"],
        False,
        CLEARANCE,
        smoothing_variant="jaxclear",
        alpha=alpha,
        beta=beta,
    )


# ------------------------------------------------------------------------ CasADi SX port
def _ramp(ca, x, w):
    """C1 positive part: 0 (x<=0), x^2/(2w) (0<x<w), x - w/2 (x>=w)."""
    return ca.if_else(x <= 0.0, 0.0, ca.if_else(x < w, x * x / (2 * w), x - 0.5 * w))


def _step_clamp(ca, x, w):
    """x * smoothstep(x/w) on (0, w), 0 below, x above (the jaxclear damping-factor clamp)."""
    u = x / w
    return ca.if_else(x <= 0.0, 0.0, ca.if_else(x >= w, x, x * u * u * (3.0 - 2.0 * u)))


def _memory_weight(ca, d, w_m):
    u = ca.fmin(ca.fmax((d + w_m) / w_m, 0.0), 1.0)
    return 1.0 - u * u * (3.0 - 2.0 * u)


def _sx_vector_field(ca, model, joints_ideal, t, y):
    """dy/dt and outputs (qdd, torque, per-joint FN, ecc) of the reference's smooth mode."""
    p = model
    q = [y[i] for i in range(9)]
    qd = [y[9 + i] for i in range(9)]
    mem = [y[18 + a] for a in range(p.nm)]
    zs = [y[p.iz + a] for a in range(p.nz)] if p.nz else [0.0] * p.nc

    def point(k, s):
        if k < 0:
            zero = (0.0, 0.0)
            return (float(s[0]), float(s[1])), zero, zero, zero
        c, sn = ca.cos(q[3 * k + 2]), ca.sin(q[3 * k + 2])
        As = (c * s[0] - sn * s[1], sn * s[0] + c * s[1])
        Bs = (-As[1], As[0])
        r = (q[3 * k] + As[0], q[3 * k + 1] + As[1])
        v = (qd[3 * k] + qd[3 * k + 2] * Bs[0], qd[3 * k + 1] + qd[3 * k + 2] * Bs[1])
        return r, v, As, Bs

    def point_acc(qdd, k, As, Bs):
        if k < 0:
            return (0.0, 0.0)
        w2 = qd[3 * k + 2] ** 2
        return (
            qdd[3 * k] + qdd[3 * k + 2] * Bs[0] - w2 * As[0],
            qdd[3 * k + 1] + qdd[3 * k + 2] * Bs[1] - w2 * As[1],
        )

    Q = [float(v) for v in p.Qg]
    cinfo = []
    for a, j in enumerate(p.cj):
        i, si, k, sk = p.joints[j]
        c, RJ, K = p.c_of[j], p.RJ_of[j], p.K_of[j]
        rI, vI, AI, BI = point(i, si)
        rII, vII, AII, BII = point(k, sk)
        ex, ey = rII[0] - rI[0], rII[1] - rI[1]
        edx, edy = vII[0] - vI[0], vII[1] - vI[1]
        e2 = ex * ex + ey * ey
        # e = hypot(ex, ey); the guards keep the AD derivatives finite at e = 0 (initial state)
        e = ca.if_else(e2 > 0.0, ca.sqrt(ca.if_else(e2 > 0.0, e2, 1.0)), 0.0)
        big = e > 1e-15
        e_safe = ca.if_else(big, e, 1.0)
        nx = ca.if_else(big, ex / e_safe, 1.0)
        ny = ca.if_else(big, ey / e_safe, 0.0)
        tx, ty = -ny, nx
        delta, ddelta = e - c, nx * edx + ny * edy
        vm = p.v_min
        dm = vm + _ramp(ca, mem[a] - vm + 0.5 * vm, vm)  # impact_floor, jaxclear variant
        fac = _step_clamp(ca, 1.0 + p.chi * ddelta / dm, p.w_factor)
        FN = K * _ramp(ca, delta, p.w_delta) ** 1.5 * fac
        if i >= 0:
            armI = (AI[0] + p.RB * nx, AI[1] + p.RB * ny)
        else:
            armI = (0.0 + p.RB * nx, 0.0 + p.RB * ny)
        armII = (AII[0] + RJ * nx, AII[1] + RJ * ny)
        if i >= 0:
            vQI = (
                vI[0] + qd[3 * i + 2] * (-armI[1] - BI[0]),
                vI[1] + qd[3 * i + 2] * (armI[0] - BI[1]),
            )
        else:
            vQI = (vI[0] + 0.0, vI[1] + 0.0)
        vQII = (
            vII[0] + qd[3 * k + 2] * (-armII[1] - BII[0]),
            vII[1] + qd[3 * k + 2] * (armII[0] - BII[1]),
        )
        vT = tx * (vQII[0] - vQI[0]) + ty * (vQII[1] - vQI[1])
        FT, zdot = _friction(ca, p, vT, FN, zs[a])
        fx, fy = -FN * nx + FT * tx, -FN * ny + FT * ty
        Q[3 * k] += fx
        Q[3 * k + 1] += fy
        Q[3 * k + 2] += armII[0] * fy - armII[1] * fx
        if i >= 0:
            Q[3 * i] -= fx
            Q[3 * i + 1] -= fy
            Q[3 * i + 2] -= armI[0] * fy - armI[1] * fx
        cinfo.append(dict(i=i, k=k, e=e, ex=ex, ey=ey, edx=edx, edy=edy, nx=nx, ny=ny, delta=delta))
        cinfo[-1].update(ddelta=ddelta, FN=FN, FT=FT, zdot=zdot, AI=AI, BI=BI, AII=AII, BII=BII)

    # constraints: ideal revolutes, slider on the x axis, slider not rotating, driver
    nrow = 2 * len(joints_ideal) + 3
    Pq = ca.SX.zeros(nrow, 9)
    Phi = [None] * nrow
    gam = [0.0] * nrow
    for r, (i, si, k, sk) in enumerate(joints_ideal):
        ri, _, Ai, Bi = point(i, si)
        rk, _, Ak, Bk = point(k, sk)
        for d in range(2):
            row = 2 * r + d
            Phi[row] = ri[d] - rk[d]
            if i >= 0:
                Pq[row, 3 * i + d] = 1.0
                Pq[row, 3 * i + 2] = Bi[d]
                gam[row] += Ai[d] * qd[3 * i + 2] ** 2
            Pq[row, 3 * k + d] = -1.0
            Pq[row, 3 * k + 2] = -Bk[d]
            gam[row] -= Ak[d] * qd[3 * k + 2] ** 2
    Pq[nrow - 3, 7], Phi[nrow - 3] = 1.0, q[7]
    Pq[nrow - 2, 8], Phi[nrow - 2] = 1.0, q[8]
    Pq[nrow - 1, 2], Phi[nrow - 1] = 1.0, q[2] - p.omega * t
    Phi_t = ca.SX.zeros(nrow)
    Phi_t[nrow - 1] = -p.omega
    qd_v, Q_v = ca.vertcat(*qd), ca.vertcat(*Q)
    Phid = ca.mtimes(Pq, qd_v) + Phi_t
    minv = ca.DM(p.minv)
    PM = Pq * ca.repmat(minv.T, nrow, 1)
    rhs = ca.vertcat(*gam) - 2 * p.alpha * Phid - p.beta**2 * ca.vertcat(*Phi)
    lam = ca.solve(ca.mtimes(PM, Pq.T), ca.mtimes(PM, Q_v) - rhs)
    qdd_v = minv * (Q_v - ca.mtimes(Pq.T, lam))
    qdd = [qdd_v[i] for i in range(9)]
    parts = [qd_v, qdd_v]
    if p.nm:
        mdot = []
        for a, ci in enumerate(cinfo):
            w = _memory_weight(ca, ci["delta"], p.w_m)
            accII = point_acc(qdd, ci["k"], ci["AII"], ci["BII"])
            accI = point_acc(qdd, ci["i"], ci["AI"], ci["BI"])
            dd = ci["nx"] * (accII[0] - accI[0]) + ci["ny"] * (accII[1] - accI[1])
            ee = ci["edx"] * ci["edx"] + ci["edy"] * ci["edy"]
            dd += (ee - ci["ddelta"] ** 2) / ca.fmax(ci["e"], 1e-3 * p.c_of[p.cj[a]])
            mdot.append(w * (dd + p.k_m * (ci["ddelta"] - mem[a])))
        parts.append(ca.vertcat(*mdot))
    if p.nz:
        parts.append(ca.vertcat(*[ci["zdot"] for ci in cinfo]))
    out = dict(
        qdd=qdd_v,
        torque=-lam[nrow - 1],
        FN=ca.vertcat(*[ci["FN"] for ci in cinfo]),
        ecc=ca.vertcat(*[ca.vertcat(ci["ex"], ci["ey"]) for ci in cinfo]),
    )
    return ca.vertcat(*parts), out


def _friction(ca, p, vT, FN, z):
    """(F_T on the journal along t, z'), the reference's ``friction_force``."""
    if p.flaw is None:
        return 0.0, 0.0
    kind, f = p.flaw
    if kind == "coulomb":
        return ca.if_else(FN > 0.0, -f["mu"] * FN * ca.tanh(vT / f["v_eps"]), 0.0), 0.0
    if kind == "modified-coulomb":
        sp = ca.fabs(vT)
        cd = (_ramp(ca, sp - f["v0"], p.w_v) - _ramp(ca, sp - f["v1"], p.w_v)) / (f["v1"] - f["v0"])
        return -f["mu"] * cd * FN * ca.sign(vT), 0.0
    speed = ca.sqrt(vT * vT + p.w_v**2)
    fade = ca.exp(-((vT / f["v_s"]) ** 2))
    g = f["mu_k"] + (f["mu_s"] - f["mu_k"]) * fade
    zdot = vT - f["sigma0"] * speed * z / g
    return -(f["sigma0"] * z + f["sigma1"] * fade * zdot + f["sigma2"] * vT) * FN, zdot


def build(case, gains=None):
    """(f, y0, meta): casadi.Function f(t, y) -> ydot of case ``case``, the reference's
    smooth-mode initial state y0, and metadata (incl. ``outputs``: Function (t, y) -> (qdd,
    torque, FN per joint, eccentricity x/y per joint), ``t``, ``y``, ``ode``: the SX symbols)."""
    import casadi as ca

    model = reference_model(case, gains)
    ref = _reference()
    ideal = [ref.JOINTS[j] for j in model.ij]
    t = ca.SX.sym("t")
    y = ca.SX.sym("y", model.n_state)
    ode, out = _sx_vector_field(ca, model, ideal, t, y)
    f = ca.Function("f", [t, y], [ode], ["t", "y"], ["ydot"])
    outputs = ca.Function(
        "outputs",
        [t, y],
        [out["qdd"], out["torque"], out["FN"], out["ecc"]],
        ["t", "y"],
        ["qdd", "torque", "FN", "ecc"],
    )
    meta = dict(
        case=case,
        label=CASES[case]["label"],
        joints=model.cj,
        friction=CASES[case]["friction"],
        n_state=model.n_state,
        alpha=model.alpha,
        beta=model.beta,
        model=model,
        outputs=outputs,
        t=t,
        y=y,
        ode=ode,
    )
    return f, model.initial_state(), meta


def output_grid(revolutions=REVOLUTIONS):
    t1 = revolutions * 60.0 / RPM
    return np.linspace(0.0, t1, int(round(revolutions * POINTS_PER_REVOLUTION)) + 1)


_JIT_DIRS = []


def _compiled_dae(meta, flags=("-O3",)):
    """The DAE oracle (t, x, z, p, u) -> (ode, alg, quad, zero) and its Jacobian as C code from
    CasADi's CodeGenerator, compiled with the system C compiler ($CC, default gcc) into a shared
    library, loaded with ``casadi.external`` (CasADi finds ``jac_dae`` in the library: CVODES's
    Jacobian is then compiled code as well).  Returns (external Function, compile seconds)."""
    import casadi as ca

    t, y, ode = meta["t"], meta["y"], meta["ode"]
    empty = [ca.SX.sym(name, 0) for name in ("z", "p", "u")]
    none = ca.SX(0, 1)
    dae = ca.Function("dae", [t, y, *empty], [ode, none, none, none], ca.dyn_in(), ca.dyn_out())
    folder = tempfile.mkdtemp(prefix="cvodes_reference_")
    if not _JIT_DIRS:
        atexit.register(lambda: [shutil.rmtree(d, ignore_errors=True) for d in _JIT_DIRS])
    _JIT_DIRS.append(folder)
    cg = ca.CodeGenerator("dae_" + meta["case"] + ".c")
    cg.add(dae)
    cg.add(dae.jacobian())
    cg.generate(folder + os.sep)
    src = os.path.join(folder, "dae_" + meta["case"] + ".c")
    lib = os.path.join(folder, "dae_" + meta["case"] + ".so")
    t0 = time.perf_counter()
    cc = os.environ.get("CC", "gcc")
    subprocess.run([cc, *flags, "-shared", "-fPIC", "-o", lib, src, "-lm"], check=True)
    return ca.external("dae", lib), time.perf_counter() - t0


def make_integrator(meta, grid, rtol=RTOL, atol=ATOL, jit=False):
    """casadi.integrator("F", "cvodes", ...) of the case on ``grid`` (grid[0] = t0 is returned as
    the first column of the output by casadi 3.8, the others are CVODES's output times).
    Returns (F, compile seconds of the C code, 0 without jit)."""
    import casadi as ca

    opts = {
        "reltol": rtol,
        "abstol": atol,
        "linear_multistep_method": "bdf",
        "nonlinear_solver_iteration": "newton",
        "max_num_steps": MAX_NUM_STEPS,
    }
    compile_s = 0.0
    if jit:
        # (options {"jit": True, "compiler": "shell"} cannot be used here: through
        # "common_options"/"specific_options" they also reach CasADi's internal Jacobian helper,
        # which rejects them; only the right-hand side could be jitted that way)
        dae, compile_s = _compiled_dae(meta)
    else:
        dae = {"t": meta["t"], "x": meta["y"], "ode": meta["ode"]}
    tout = np.asarray(grid, float)
    return ca.integrator("F", "cvodes", dae, float(tout[0]), tout, opts), compile_s


def cycle_stats(meta, grid, Y, revolutions=REVOLUTIONS):
    """RMS slider acceleration / crank torque over the last revolution (bench_clearance's
    selection), peak F_N per joint over the whole grid."""
    fn = meta["outputs"].map(len(grid))
    qdd, torque, FN, _ = fn(grid[None, :], Y)
    acc, torque, FN = np.array(qdd)[6], np.array(torque).ravel(), np.array(FN)
    sel = grid >= grid[-1] - 60.0 / RPM - 1e-12 if revolutions >= 2 else np.ones(grid.shape, bool)
    return dict(
        rms_acc=float(np.sqrt(np.mean(acc[sel] ** 2))),
        rms_torque=float(np.sqrt(np.mean(torque[sel] ** 2))),
        peak_fn={j: float(FN[a].max()) for a, j in enumerate(meta["joints"])},
    )


def cvodes_run(case, repeats=3, jit=False):
    """Time CVODES on case ``case`` (2 revolutions, 721 points): dict with run_s (median of
    ``repeats`` calls after a warm-up), run_min_s, build_s (SX graph and integrator
    construction, with jit the C compile too: compile_s), steps (CVODES successful steps),
    steps_attempted (+ error-test and Newton failures, comparable with diffrax num_steps),
    rhs_evals, jac_evals, newton_iters, error_test_fails, newton_conv_fails, the raw CVODES
    counters, and cycle statistics (rms_acc, rms_torque, peak_fn per joint)."""
    baumgarte_gains()  # (imports jaxclear once: not part of build_s)
    t0 = time.perf_counter()
    f, y0, meta = build(case)
    grid = output_grid()
    F, compile_s = make_integrator(meta, grid, jit=jit)
    build_s = time.perf_counter() - t0
    F(x0=y0)  # warm-up
    times = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        res = F(x0=y0)
        times.append(time.perf_counter() - t0)
    st = F.stats()
    Y = np.array(res["xf"])  # (n_state, 721): casadi 3.8 returns x0 at tout[0] = t0
    assert Y.shape == (meta["n_state"], grid.size) and np.array_equal(Y[:, 0], y0)
    counters = {k: st[k] for k in sorted(st) if k.startswith("n") and not k.endswith("B")}
    return dict(
        case=case,
        solver="cvodes-bdf" + ("-jit" if jit else "-sx"),
        jit=bool(jit),
        run_s=statistics.median(times),
        run_min_s=min(times),
        build_s=build_s,
        compile_s=compile_s,
        steps=int(st["nsteps"]),  # CVODES nst: successful steps
        steps_attempted=int(st["nsteps"] + st["netfails"] + st["nncfails"]),
        rhs_evals=int(st["nfevals"]),
        jac_evals=int(st.get("n_call_jacF", st["nlinsetups"])),
        newton_iters=int(st["nniters"]),
        error_test_fails=int(st["netfails"]),
        newton_conv_fails=int(st["nncfails"]),
        counters={k: int(v) for k, v in counters.items()},
        stat_keys=sorted(st),
        n_state=meta["n_state"],
        rtol=RTOL,
        atol=ATOL,
        stats=cycle_stats(meta, grid, Y),
        succeeded=bool(np.all(np.isfinite(Y))),
    )


# ----------------------------------------------------------------------------------- check
def check_case(case, n_states=20, t_states=2e-3, t_traj=1e-3, rtol_traj=1e-10):
    """Right-hand side and a 1 ms trajectory of the port against the SciPy reference."""
    import casadi as ca
    from scipy.integrate import solve_ivp

    f, y0, meta = build(case)
    model = meta["model"]

    def ref_f(t, y):
        return model.evaluate(t, y)[0]

    # states along a reference solve of the first t_states (Radau, as the reference runs)
    sol = solve_ivp(
        ref_f,
        (0.0, t_states),
        y0,
        method="Radau",
        rtol=1e-8,
        atol=1e-11,
        t_eval=np.linspace(0.0, t_states, n_states + 1)[1:],
    )
    states = [(0.0, y0)] + list(zip(sol.t, sol.y.T))
    FR = np.array([ref_f(t, y) for t, y in states])
    FC = np.array([np.array(f(t, y)).ravel() for t, y in states])
    n_contact = sum(
        any(ci["FN"] > 0 for ci in model.evaluate(t, y)[1]["contacts"]) for t, y in states
    )
    # scale of each block of y' (q', q'', m', z') over the states: the rounding noise of
    # components that vanish by cancellation (e.g. 3e-30 for a zero y-acceleration) is relative
    # to it, so the plain per-component ratio is also shown restricted to components >= 1e-6 of it
    blocks = [slice(0, 9), slice(9, 18), slice(18, 18 + model.nm), slice(model.iz, model.n_state)]
    scale = np.zeros(model.n_state)
    for b in blocks:
        if b.stop > b.start:
            scale[b] = np.abs(FR[:, b]).max()
    diff = np.abs(FC - FR)
    raw = diff / (np.abs(FR) + 1e-300)
    big = np.abs(FR) >= 1e-6 * scale
    worst = float(raw[big].max())
    n_small = int((~big).sum())
    n_zero = int(((FR == 0) & (FC == 0)).sum())
    worst_scaled = float((diff / scale).max())
    # Jacobian finite everywhere (incl. the initial state, e = 0)
    jac = ca.Function("jac_f", [meta["t"], meta["y"]], [ca.jacobian(meta["ode"], meta["y"])])
    jac_finite = all(np.all(np.isfinite(np.array(jac(t, y)))) for t, y in states)

    # the compiled C code of --jit against the SX functions (right-hand side and Jacobian)
    try:
        ext, _ = _compiled_dae(meta)
        jit_rel = 0.0
        for t, y in states:
            pairs = [(ext(t, y, [], [], [])[0], f(t, y))]
            pairs.append((ext.jacobian()(t, y, [], [], [], 0, [], [], [])[1], jac(t, y)))
            for a_, b_ in pairs:
                a_, b_ = np.array(ca.densify(a_)), np.array(ca.densify(b_))
                jit_rel = max(jit_rel, float(np.max(np.abs(a_ - b_) / (np.abs(b_) + 1e-300))))
    except (OSError, subprocess.CalledProcessError) as exc:  # no C compiler
        jit_rel = f"not checked ({exc})"

    # trajectory: CVODES (rtol 1e-10) vs SciPy DOP853 (rtol 1e-10) over the first t_traj
    grid = np.linspace(0.0, t_traj, 201)
    F, _ = make_integrator(meta, grid, rtol=rtol_traj, atol=rtol_traj * 1e-3)
    Yc = np.array(F(x0=y0)["xf"])
    t_ref = time.perf_counter()
    sr = solve_ivp(
        ref_f,
        (0.0, t_traj),
        y0,
        method="DOP853",
        rtol=rtol_traj,
        atol=rtol_traj * 1e-3,
        t_eval=grid,
    )
    t_ref = time.perf_counter() - t_ref
    Yr = sr.y
    ecc = meta["outputs"].map(len(grid))
    Ec = np.array(ecc(grid[None, :], Yc)[3])
    Er = np.array(ecc(grid[None, :], Yr)[3])
    ecc_um = {
        j: 1e6 * float(np.max(np.hypot(*(Ec[2 * a : 2 * a + 2] - Er[2 * a : 2 * a + 2]))))
        for a, j in enumerate(meta["joints"])
    }
    peak_ecc = {
        j: 1e6 * float(np.max(np.hypot(*Er[2 * a : 2 * a + 2])))
        for a, j in enumerate(meta["joints"])
    }
    fn = np.array(ecc(grid[None, :], Yr)[2])
    return dict(
        case=case,
        rhs_max_rel_diff=worst,
        rhs_components_excluded=f"{n_small} of {big.size} ({n_zero} exactly 0 in both)",
        rhs_max_diff_over_scale=worst_scaled,
        n_states=len(states),
        states_in_contact=n_contact,
        jacobian_finite=bool(jac_finite),
        jit_vs_sx_max_rel_diff=jit_rel,
        traj_slider_x_um=1e6 * float(np.max(np.abs(Yc[6] - Yr[6]))),
        traj_ecc_um=ecc_um,
        traj_peak_ecc_um=peak_ecc,
        traj_peak_fn={j: float(fn[a].max()) for a, j in enumerate(meta["joints"])},
        cvodes_steps_1ms=int(F.stats()["nsteps"]),
        scipy_dop853_s=t_ref,
    )


def _fmt(x):
    """A figure as 1.2e-03, or the text that says why it is missing (no C compiler)."""
    return x if isinstance(x, str) else f"{x:.1e}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="a,b,c")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--jit", action="store_true", help="compile the generated C with gcc -O3")
    ap.add_argument("--json", action="store_true", help="one JSON line per case")
    ap.add_argument("--check", action="store_true", help="compare with the SciPy reference")
    args = ap.parse_args(argv)
    cases = [c for c in args.cases.split(",") if c]
    if args.check:
        for case in cases:
            r = check_case(case)
            if args.json:
                print(json.dumps(r))
                continue
            print(
                f"case {case}: RHS max rel diff {r['rhs_max_rel_diff']:.2e} (components >= 1e-6 "
                f"of their block's scale; {r['rhs_components_excluded']} excluded), all "
                f"components max |diff|/scale {r['rhs_max_diff_over_scale']:.1e}, over "
                f"{r['n_states']} "
                f"states ({r['states_in_contact']} in contact), Jacobian finite "
                f"{r['jacobian_finite']}, jit C vs SX (f and Jacobian) max rel diff "
                f"{_fmt(r['jit_vs_sx_max_rel_diff'])}; 1 ms CVODES vs DOP853 (rtol 1e-10): slider x "
                f"{r['traj_slider_x_um']:.2e} um, ecc "
                + ", ".join(f"{j} {v:.2e} um" for j, v in r["traj_ecc_um"].items())
                + " (peak |e| "
                + ", ".join(f"{j} {v:.0f} um" for j, v in r["traj_peak_ecc_um"].items())
                + ", peak FN "
                + ", ".join(f"{j} {v:.0f} N" for j, v in r["traj_peak_fn"].items())
                + ")",
                flush=True,
            )
        return
    for case in cases:
        r = cvodes_run(case, args.repeats, args.jit)
        if args.json:
            print(json.dumps(r), flush=True)
            continue
        s = r["stats"]
        print(
            f"case {case} {r['solver']}: run {r['run_s']:.4f} s (min {r['run_min_s']:.4f}, "
            f"build {r['build_s']:.2f} s incl. C compile {r['compile_s']:.2f} s), "
            f"steps {r['steps']} (+ {r['error_test_fails']} error-test, "
            f"{r['newton_conv_fails']} Newton failures), rhs {r['rhs_evals']}, "
            f"jac {r['jac_evals']}, newton iters {r['newton_iters']}; "
            f"rms acc {s['rms_acc']:.0f} m/s2, rms torque {s['rms_torque']:.2f} N m, peak FN "
            + ", ".join(f"{j} {v:.0f} N" for j, v in s["peak_fn"].items()),
            flush=True,
        )
        if case == cases[0]:
            print(f"  F.stats() keys: {' '.join(r['stat_keys'])}", flush=True)


if __name__ == "__main__":
    main()
