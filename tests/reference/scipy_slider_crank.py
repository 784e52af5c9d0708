"""Independent NumPy/SciPy reference: slider-crank with revolute clearance joints.

Shares nothing with ``jaxclear`` except the parameter values of docs/model.md §6.  Cartesian coordinates
q = (x, y, phi) for crank (body 0), rod (1), slider (2); ground has no coordinates.  Hand-written
constraint Jacobians, index-1 equations with Baumgarte stabilisation, multipliers from the Schur
complement (M is diagonal).  Two contact modes:

* ``"sharp"``: the hybrid model; events on delta = e - c, impact velocity latched at each onset;
  a joint in free flight gets no contact force (so the vector field is smooth between events and
  the steps that end at an event are not polluted by forces beyond it).  An onset the event
  search misses (delta up and down inside one step) raises RuntimeError once the journal is
  found past the wall (> 1e-11 m at a segment end or sample); ``max_step`` bounds such misses;
* ``"smooth"``: docs/model.md §5 -- C1 ramps for the penetration and the damping factor, and an
  impact-velocity memory state m per joint, m' = w(delta) [d(delta')/dt + k_m (delta' - m)].

State y = (q[9], qd[9], m[n_clearance] (smooth mode only), z[n_clearance] (LuGre friction only),
W (drive work, optional)).

Friction (``friction=``, docs/model.md §4), the formulas and smoothings re-implemented in NumPy:
* ``("coulomb", mu, v_eps)``: F_T = -mu F_N tanh(v_T/v_eps);
* ``("modified-coulomb", mu, v0=1e-4, v1=1e-3)``: F_T = -mu c_d(|v_T|) F_N sgn(v_T) with
  c_d = [ramp(|v| - v0, w_v) - ramp(|v| - v1, w_v)] / (v1 - v0) (corners rounded by ``ramp``);
* ``("lugre", sigma0=1e5, sigma1=316, sigma2=0, mu_s=0.15, mu_k=0.1, v_s=1e-3)``: a state z per
  clearance joint, z' = v - sigma0 |v|_s z / g(v), g = mu_k + (mu_s - mu_k) exp(-(v/v_s)^2),
  F_T = -(sigma0 z + sigma1 exp(-(v/v_s)^2) z' + sigma2 v) F_N, |v|_s = sqrt(v^2 + w_v^2).
w_v (default 1e-5 m/s) is the velocity smoothing width.

Smooth-mode regularisation variants (``smoothing_variant``): ``"jaxclear"`` (default) uses the
same C1 shapes as the package: damping factor clamped by x * smoothstep(x/w_factor) (exact for
x >= w_factor), impact velocity floored by v_min + ramp(m - v_min/2, v_min), and the curvature term
of m' evaluated at e >= 1e-3 c; ``"original"`` keeps this module's first choices: factor clamped by
ramp(x, w_factor) (shifted by w_factor/2), hyperbolic smooth max for the floor, the curvature term
dropped only at e = 0.  The differences are O(w_factor) = 1e-3 relative in F_N and O(v_min) in the
floor; they matter only for comparing the two codes as the *same* model.
Sign conventions: crank_torque > 0 means the motor does positive work when omega > 0; the reaction
of an ideal joint is the force magnitude |lambda_J|.  Eccentricities are global x/y components.

Per-joint options: ``clearance`` is a float (every clearance joint) or a mapping joint -> c (m),
e.g. ``{"A": 3.5e-4, "B": 2.5e-4}``; the journal radius is R_B - c and the Hertz K is the joint's.
``journal_body`` maps a joint to the body that carries its pin, e.g. ``{"B": "rod"}`` ("pin on
the rod": bearing hole in the slider at (0, 0), pin on the rod at (L/2, 0)); by default the pin is
on the joint's second body of ``JOINTS`` (O: crank, A: rod, B: slider), as in jaxclear's
``ClearanceJoint.replacing``.  Whichever body carries it, e = r_journal - r_bearing, the force
f = -F_N n + F_T t acts on the journal at r_journal + R_J n and -f on the bearing at
r_bearing + R_B n.  Journals start centred (e = 0) with the ideal-joint velocities.
``simulate(t_eval=...)`` returns the signals on any increasing time grid from t >= 0.
"""

import time

import numpy as np
from scipy.integrate import solve_ivp

R_CRANK, L_ROD = 0.05, 0.12
MASS = (0.30, 0.21, 0.14)
INERTIA = (1.0e-4, 2.5e-4, 1.0e-4)
GRAV = 9.81
# joint -> (bearing body, point on it, journal body, point on it); body -1 is ground
EYE2 = np.eye(2)
JOINTS = {
    "O": (-1, (0.0, 0.0), 0, (-R_CRANK / 2, 0.0)),
    "A": (0, (R_CRANK / 2, 0.0), 1, (-L_ROD / 2, 0.0)),
    "B": (1, (L_ROD / 2, 0.0), 2, (0.0, 0.0)),
}
BODY_INDEX = {"ground": -1, "crank": 0, "rod": 1, "slider": 2}


def joint_geometry(j, journal_body=None):
    """(bearing body, its point, journal body, its point) of joint j with the pin on journal_body
    (a name in BODY_INDEX; None: the default of JOINTS, pin on the second body)."""
    i, si, k, sk = JOINTS[j]
    if journal_body is None or BODY_INDEX[journal_body] == k:
        return i, si, k, sk
    if BODY_INDEX[journal_body] != i:
        names = [n for n, b in BODY_INDEX.items() if b in (i, k)]
        raise ValueError(f"journal_body of joint {j} must be one of {names}, got {journal_body!r}")
    return k, sk, i, si


def ideal_closed_form(theta, omega, r=R_CRANK, rod=L_ROD):
    """Slider x, v, a for x = r cos(th) + sqrt(l^2 - r^2 sin^2(th)), l = rod, th = omega t (exact derivatives)."""
    th = np.asarray(theta, dtype=float)
    s, c = np.sin(th), np.cos(th)
    S = np.sqrt(rod**2 - r**2 * s**2)
    x = r * c + S
    dx = -r * s - r**2 * s * c / S
    ddx = -r * c - r**2 * (c**2 - s**2) / S - r**4 * s**2 * c**2 / S**3
    return {"x": x, "v": omega * dx, "a": omega**2 * ddx}


def ramp(x, w):
    """C1 positive part: 0 (x<=0), x^2/(2w) (0<x<w), x - w/2 (x>=w)."""
    if x <= 0.0:
        return 0.0
    return x * x / (2 * w) if x < w else x - 0.5 * w


def ramp_potential(d, w):
    """int_0^d ramp(s, w)^1.5 ds (for the energy of the smooth, undamped law)."""
    if d <= 0.0:
        return 0.0
    if d < w:
        return d**4 / (4.0 * (2.0 * w) ** 1.5)
    return w**4 / (4.0 * (2.0 * w) ** 1.5) + 0.4 * ((d - 0.5 * w) ** 2.5 - (0.5 * w) ** 2.5)


def step_clamp(x, w):
    """C1 max(x, 0) exact outside (0, w): x * smoothstep(x/w) (jaxclear's clamp_nonnegative)."""
    if x <= 0.0:
        return 0.0
    if x >= w:
        return x
    u = x / w
    return x * u * u * (3.0 - 2.0 * u)


def friction_law(spec):
    """Normalise a ``friction=`` tuple to (kind, params dict); None for no friction."""
    if spec is None:
        return None
    kind, args = spec[0], tuple(spec[1:])
    names = {
        "coulomb": ("mu", "v_eps"),
        "modified-coulomb": ("mu", "v0", "v1"),
        "lugre": ("sigma0", "sigma1", "sigma2", "mu_s", "mu_k", "v_s"),
    }
    defaults = {
        "coulomb": {},
        "modified-coulomb": dict(v0=1e-4, v1=1e-3),
        "lugre": dict(sigma0=1e5, sigma1=316.0, sigma2=0.0, mu_s=0.15, mu_k=0.1, v_s=1e-3),
    }
    if kind not in names:
        raise ValueError(f"unknown friction law {kind!r}; choose one of {sorted(names)}")
    if len(args) > len(names[kind]):
        raise ValueError(f"{kind}: at most {len(names[kind])} parameters {names[kind]}")
    par = dict(defaults[kind], **dict(zip(names[kind], args)))
    missing = set(names[kind]) - set(par)
    if missing:
        raise ValueError(f"{kind}: missing parameters {sorted(missing)}")
    return kind, par


def memory_weight(d, w_m):
    """1 for d <= -w_m, 0 for d >= 0, cubic smoothstep in between."""
    u = min(max((d + w_m) / w_m, 0.0), 1.0)
    return 1.0 - u * u * (3.0 - 2.0 * u)


def _point(q, qd, k, s):
    """Position, velocity, A s and B s of local point s on body k (k = -1: ground point)."""
    if k < 0:
        z = np.zeros(2)
        return np.array(s, float), z, z, z
    c, sn = np.cos(q[3 * k + 2]), np.sin(q[3 * k + 2])
    As = np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]])
    Bs = np.array([-As[1], As[0]])
    return q[3 * k : 3 * k + 2] + As, qd[3 * k : 3 * k + 2] + qd[3 * k + 2] * Bs, As, Bs


def _point_acc(qd, qdd, k, As, Bs):
    if k < 0:
        return np.zeros(2)
    return qdd[3 * k : 3 * k + 2] + qdd[3 * k + 2] * Bs - qd[3 * k + 2] ** 2 * As


def _kx(a):
    return np.array([-a[1], a[0]])


def _cross(a, f):
    return a[0] * f[1] - a[1] * f[0]


class SliderCrank:
    def __init__(
        self,
        clearance_joints=("B",),
        rpm=5000.0,
        mode="smooth",
        restitution=0.9,
        friction=None,
        gravity=False,
        clearance=5e-4,
        bearing_radius=0.01,
        E=207e9,
        nu=0.3,
        alpha=5.0,
        beta=5.0,
        w_delta=1e-7,
        w_m=1e-7,
        k_m=1e6,
        v_min=1e-4,
        w_factor=1e-3,
        track_work=False,
        w_v=1e-5,
        smoothing_variant="jaxclear",
        journal_body=None,
    ):
        assert mode in ("smooth", "sharp") and set(clearance_joints) <= set("OAB")
        assert smoothing_variant in ("jaxclear", "original"), smoothing_variant
        self.cj = tuple(j for j in "OAB" if j in clearance_joints)
        self.ij = tuple(j for j in "OAB" if j not in self.cj)
        self.mode, self.omega, self.track_work = mode, rpm * np.pi / 30.0, track_work
        journal_body = dict(journal_body or {})
        if isinstance(clearance, dict):
            if set(clearance) != set(self.cj):
                raise ValueError(f"clearance: give one value per clearance joint {self.cj}")
            cs = {j: float(clearance[j]) for j in self.cj}
        else:
            cs = {j: float(clearance) for j in self.cj}
        if not set(journal_body) <= set(self.cj):
            raise ValueError(f"journal_body: joints must be among the clearance joints {self.cj}")
        self.joints = {j: joint_geometry(j, journal_body.get(j)) for j in self.cj}
        self.journal_body = {
            j: next(n for n, b in BODY_INDEX.items() if b == self.joints[j][2]) for j in self.cj
        }
        sigma = (1 - nu**2) / E
        self.RB = bearing_radius
        self.c_of = cs  # per clearance joint: c, R_J = R_B - c, Hertz K (docs/model.md §3)
        self.RJ_of = {j: bearing_radius - c for j, c in cs.items()}
        self.K_of = {
            j: 4.0 / (3.0 * 2 * sigma) * np.sqrt(bearing_radius * self.RJ_of[j] / c)
            for j, c in cs.items()
        }
        if not isinstance(clearance, dict):  # the scalar attributes of a common clearance
            self.c, self.RJ = clearance, bearing_radius - clearance
            self.K = 4.0 / (3.0 * 2 * sigma) * np.sqrt(self.RB * self.RJ / clearance)
        self.chi = 0.75 * (1.0 - restitution**2)
        self.friction = friction
        self.flaw = friction_law(friction)
        self.w_v, self.variant = w_v, smoothing_variant
        self.alpha, self.beta = alpha, beta
        self.w_delta, self.w_m, self.k_m, self.v_min, self.w_factor = (
            w_delta,
            w_m,
            k_m,
            v_min,
            w_factor,
        )
        self.minv = 1.0 / np.array([v for k in range(3) for v in (MASS[k], MASS[k], INERTIA[k])])
        self.Qg = np.zeros(9)
        if gravity:
            self.Qg[[1, 4, 7]] = -GRAV * np.array(MASS)
        self.nc = len(self.cj)
        self.nm = self.nc if mode == "smooth" else 0
        self.nz = self.nc if (self.flaw and self.flaw[0] == "lugre") else 0
        self.iz = 18 + self.nm  # first LuGre state
        self.n_state = 18 + self.nm + self.nz + (1 if track_work else 0)
        self.n_eval = 0  # all right-hand-side evaluations (incl. finite-difference Jacobians)

    # ---- constraints: ideal revolutes, translational (y2 = 0, phi2 = 0), driver phi0 = omega t
    def constraints(self, t, q, qd):
        nrow = 2 * len(self.ij) + 3
        Pq, Phi, gam = np.zeros((nrow, 9)), np.zeros(nrow), np.zeros(nrow)
        for r, j in enumerate(self.ij):
            i, si, k, sk = JOINTS[j]
            rows = slice(2 * r, 2 * r + 2)
            ri, _, Ai, Bi = _point(q, qd, i, si)
            rk, _, Ak, Bk = _point(q, qd, k, sk)
            Phi[rows] = ri - rk
            if i >= 0:
                Pq[rows, 3 * i : 3 * i + 2] = EYE2
                Pq[rows, 3 * i + 2] = Bi
                gam[rows] += Ai * qd[3 * i + 2] ** 2
            Pq[rows, 3 * k : 3 * k + 2] = -EYE2
            Pq[rows, 3 * k + 2] = -Bk
            gam[rows] -= Ak * qd[3 * k + 2] ** 2
        Pq[-3, 7], Phi[-3] = 1.0, q[7]  # slider on the x axis
        Pq[-2, 8], Phi[-2] = 1.0, q[8]  # slider does not rotate
        Pq[-1, 2], Phi[-1] = 1.0, q[2] - self.omega * t  # driver
        Phi_t = np.zeros(nrow)
        Phi_t[-1] = -self.omega
        return Phi, Pq, gam, Pq @ qd + Phi_t

    # ---- clearance joint kinematics and forces (added to Q); returns per-joint info
    def factor_clamp(self, x):
        """Smooth max(x, 0) of the damping factor (smooth mode)."""
        if self.variant == "jaxclear":
            return step_clamp(x, self.w_factor)
        return ramp(x, self.w_factor)

    def impact_floor(self, m):
        """Smooth max(m, v_min) of the memorised impact velocity (smooth mode)."""
        vm = self.v_min
        if self.variant == "jaxclear":
            return vm + ramp(m - vm + 0.5 * vm, vm)
        return 0.5 * (m + vm + np.sqrt((m - vm) ** 2 + (0.1 * vm) ** 2))

    def friction_force(self, vT, FN, z):
        """(F_T on the journal along t, z') for the slip velocity vT, normal force FN, state z."""
        if self.flaw is None:
            return 0.0, 0.0
        kind, p = self.flaw
        if kind == "coulomb":
            return (-p["mu"] * FN * np.tanh(vT / p["v_eps"]) if FN > 0.0 else 0.0), 0.0
        if kind == "modified-coulomb":
            sp = abs(vT)
            cd = (ramp(sp - p["v0"], self.w_v) - ramp(sp - p["v1"], self.w_v)) / (p["v1"] - p["v0"])
            return -p["mu"] * cd * FN * np.sign(vT), 0.0
        speed = np.sqrt(vT * vT + self.w_v**2)
        fade = np.exp(-((vT / p["v_s"]) ** 2))
        g = p["mu_k"] + (p["mu_s"] - p["mu_k"]) * fade
        zdot = vT - p["sigma0"] * speed * z / g
        return -(p["sigma0"] * z + p["sigma1"] * fade * zdot + p["sigma2"] * vT) * FN, zdot

    def contact(self, j, q, qd, Q, dminus, z=0.0, active=True):
        """Kinematics and forces of clearance joint j (forces added to Q).  ``active=False``
        (sharp mode, joint in free flight) applies no contact force whatever delta is."""
        i, si, k, sk = self.joints[j]
        c, RJ, K = self.c_of[j], self.RJ_of[j], self.K_of[j]
        rI, vI, AI, BI = _point(q, qd, i, si)
        rII, vII, AII, BII = _point(q, qd, k, sk)
        e_vec, edot = rII - rI, vII - vI
        e = np.hypot(e_vec[0], e_vec[1])
        n = e_vec / e if e > 1e-15 else np.array([1.0, 0.0])
        t_vec = np.array([-n[1], n[0]])
        delta, ddelta = e - c, n @ edot
        if self.mode == "sharp":
            fac = max(0.0, 1.0 + self.chi * ddelta / dminus)
            FN = K * max(delta, 0.0) ** 1.5 * fac if active else 0.0
        else:
            dm = self.impact_floor(dminus)  # memory state; smooth max with v_min
            fac = self.factor_clamp(1.0 + self.chi * ddelta / dm)
            FN = K * ramp(delta, self.w_delta) ** 1.5 * fac
        armI = (AI if i >= 0 else 0.0) + self.RB * n  # CM -> contact point Q_I
        armII = AII + RJ * n  # CM -> contact point Q_II
        # material velocities of the contact points: v_P + phi' k x (arm - A s)
        vQI = vI + (qd[3 * i + 2] * (_kx(armI) - BI) if i >= 0 else 0.0)
        vQII = vII + qd[3 * k + 2] * (_kx(armII) - BII)
        vT = t_vec @ (vQII - vQI)
        FT, zdot = self.friction_force(vT, FN, z)
        f = -FN * n + FT * t_vec  # on the journal
        Q[3 * k : 3 * k + 2] += f
        Q[3 * k + 2] += _cross(armII, f)
        if i >= 0:
            Q[3 * i : 3 * i + 2] -= f
            Q[3 * i + 2] -= _cross(armI, f)
        return dict(
            e_vec=e_vec,
            e=e,
            n=n,
            edot=edot,
            delta=delta,
            ddelta=ddelta,
            FN=FN,
            FT=FT,
            vT=vT,
            zdot=zdot,
            z=z,
            i=i,
            k=k,
            AI=AI,
            BI=BI,
            AII=AII,
            BII=BII,
        )

    def evaluate(self, t, y, dminus=None, active=None):
        """Full evaluation: returns (ydot, info dict).

        Sharp mode: ``dminus`` the latched impact velocities, ``active`` which joints are in
        their contact phase (None: all; a joint in free flight gets no force, so that each
        segment between events has a smooth vector field)."""
        self.n_eval += 1
        q, qd = y[:9], y[9:18]
        mem = y[18 : 18 + self.nm] if self.mode == "smooth" else dminus
        Q = self.Qg.copy()
        zs = y[self.iz : self.iz + self.nz] if self.nz else np.zeros(self.nc)
        act = [True] * self.nc if active is None else active
        cinfo = [self.contact(j, q, qd, Q, mem[a], zs[a], act[a]) for a, j in enumerate(self.cj)]
        Phi, Pq, gam, Phid = self.constraints(t, q, qd)
        PM = Pq * self.minv
        rhs = gam - 2 * self.alpha * Phid - self.beta**2 * Phi
        lam = np.linalg.solve(PM @ Pq.T, PM @ Q - rhs)
        qdd = self.minv * (Q - Pq.T @ lam)
        torque = -lam[-1]
        ydot = [qd, qdd]
        if self.mode == "smooth":
            mdot = np.zeros(self.nc)
            for a, ci in enumerate(cinfo):
                w = memory_weight(ci["delta"], self.w_m)
                if w > 0.0:
                    eacc = _point_acc(qd, qdd, ci["k"], ci["AII"], ci["BII"]) - _point_acc(
                        qd, qdd, ci["i"], ci["AI"], ci["BI"]
                    )
                    dd = ci["n"] @ eacc
                    if self.variant == "jaxclear":  # (t'e')^2 / max(e, 1e-3 c)
                        dd += (ci["edot"] @ ci["edot"] - ci["ddelta"] ** 2) / max(
                            ci["e"], 1e-3 * self.c_of[self.cj[a]]
                        )
                    elif ci["e"] > 1e-15:
                        dd += (ci["edot"] @ ci["edot"] - ci["ddelta"] ** 2) / ci["e"]
                    mdot[a] = w * (dd + self.k_m * (ci["ddelta"] - mem[a]))
            ydot.append(mdot)
        if self.nz:
            ydot.append([ci["zdot"] for ci in cinfo])
        if self.track_work:
            ydot.append([torque * qd[2]])
        return np.concatenate(ydot), dict(qdd=qdd, lam=lam, torque=torque, contacts=cinfo)

    def initial_state(self):
        """Crank angle 0 (outer dead centre), ideal-joint positions/velocities, journals centred."""
        q = np.array([R_CRANK / 2, 0, 0, R_CRANK + L_ROD / 2, 0, 0, R_CRANK + L_ROD, 0, 0], float)
        full = SliderCrank(clearance_joints=(), rpm=self.omega * 30 / np.pi)
        _, Pq, _, _ = full.constraints(0.0, q, np.zeros(9))
        Phi_t = np.zeros(9)
        Phi_t[-1] = -self.omega
        qd = np.linalg.solve(Pq, -Phi_t)
        y = np.zeros(self.n_state)
        y[:9], y[9:18] = q, qd
        if self.mode == "smooth":  # m = delta' (= 0 at the start, n arbitrary at e = 0)
            y[18 : 18 + self.nm] = [
                self.contact(j, q, qd, np.zeros(9), 1.0)["ddelta"] for j in self.cj
            ]
        return y

    def energy(self, y):
        """Kinetic + contact potential (+ gravity) energy; in smooth mode the undamped law."""
        qd = y[9:18]
        T = 0.5 * np.sum(qd**2 / self.minv)
        V = -self.Qg @ y[:9]
        for j in self.cj:
            d = self.contact(j, y[:9], qd, np.zeros(9), 1.0)["delta"]
            if self.mode == "sharp":
                V += 0.4 * self.K_of[j] * max(d, 0.0) ** 2.5
            else:
                V += self.K_of[j] * self.factor_clamp(1.0) * ramp_potential(d, self.w_delta)
        return T + V


def _delta_event(model, a, offset, direction, terminal):
    j = model.cj[a]

    def ev(t, y):
        return model.contact(j, y[:9], y[9:18], np.zeros(9), 1.0)["delta"] + offset

    ev.direction, ev.terminal = direction, terminal
    return ev


def simulate(
    clearance_joints=("B",),
    rpm=5000,
    revolutions=2,
    points_per_revolution=360,
    mode="smooth",
    method=None,
    rtol=1e-6,
    atol=1e-9,
    restitution=0.9,
    friction=None,
    gravity=False,
    clearance=5e-4,
    max_step=np.inf,
    track_work=False,
    count_onsets=True,
    t_eval=None,
    journal_body=None,
    **smoothing,
):
    """Simulate; returns dict of arrays on the uniform grid t (or on ``t_eval``) plus 'stats'.

    clearance: m, a float or a mapping joint -> clearance (module doc).
    journal_body: None or a mapping joint -> body carrying the pin, e.g. {"B": "rod"} (module doc).
    t_eval: increasing output times >= 0, s; the run starts at t = 0 and ends at t_eval[-1]
    (``revolutions`` and ``points_per_revolution`` are then ignored).

    smoothing: w_delta, w_m, k_m, v_min, w_factor (smooth mode; v_min also floors the latched
    impact velocity in sharp mode), smoothing_variant ("jaxclear" or "original", see the module
    doc), w_v (velocity width of the friction laws), alpha, beta (Baumgarte), bearing_radius, E, nu.
    friction: None, ("coulomb", mu, v_eps), ("modified-coulomb", mu[, v0, v1]) or
    ("lugre"[, sigma0, sigma1, sigma2, mu_s, mu_k, v_s]) (module doc).
    count_onsets: smooth mode only; False drops the (non-terminal) delta = 0 events that count
    contact onsets (stats onsets then 0), e.g. for timing the bare integration.
    """
    model = SliderCrank(
        clearance_joints,
        rpm,
        mode,
        restitution,
        friction,
        gravity,
        clearance,
        track_work=track_work,
        journal_body=journal_body,
        **smoothing,
    )
    method = method or ("Radau" if mode == "smooth" else "DOP853")
    if t_eval is None:
        T = revolutions * 60.0 / rpm
        npts = int(round(revolutions * points_per_revolution)) + 1
        grid = np.linspace(0.0, T, npts)
    else:
        grid = np.array(t_eval, dtype=float)
        if grid.ndim != 1 or grid.size < 2 or grid[0] < 0 or np.any(np.diff(grid) <= 0):
            raise ValueError("t_eval: need at least two increasing times >= 0")
        T, npts = float(grid[-1]), grid.size
    y0 = model.initial_state()
    t_wall = time.perf_counter()
    errstate = np.errstate(over="ignore", invalid="ignore")  # rejected explicit trial steps
    errstate.__enter__()
    nfev, njev, onsets = 0, 0, np.zeros(model.nc, int)
    ys, ctx = [], []  # output states and the latched impact velocities in force at each
    if mode == "smooth":
        events = (
            [_delta_event(model, a, 0.0, 1, False) for a in range(model.nc)] if count_onsets else []
        )
        sol = solve_ivp(
            lambda t, y: model.evaluate(t, y)[0],
            (0.0, T),
            y0,
            method=method,
            t_eval=grid,
            events=events or None,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
        )
        if sol.status < 0:
            raise RuntimeError(sol.message)
        nfev, njev = sol.nfev, sol.njev
        if sol.t_events is not None:
            onsets[:] = [len(te) for te in sol.t_events]
        ys, ctx = list(sol.y.T), [(None, None)] * npts
    else:
        HYST = 1e-14  # m: exit event fires at delta = -1e-14 so it cannot stick at a restart
        # A joint in free flight gets no force, so an onset that the event search misses (delta
        # up and down again inside one step: the free-flight vector field is smooth and its steps
        # can be long) lets the journal pass the wall.  Caught at every segment end and sample.
        MISSED = 1e-11  # m: delta > MISSED in free flight is a missed onset

        def check_free(t, y, active):
            for a, j in enumerate(model.cj):
                d = model.contact(j, y[:9], y[9:18], np.zeros(9), 1.0)["delta"]
                if not active[a] and d > MISSED:
                    raise RuntimeError(
                        f"sharp mode missed a contact onset at joint {j}: delta = {d:.3g} m in "
                        f"free flight at t = {t:.9g} s; pass a smaller max_step (now {max_step})"
                    )

        in_contact = np.zeros(model.nc, bool)
        dminus = np.full(model.nc, model.v_min)
        t0, y, nseg = 0.0, y0, 0
        while len(ys) < npts:
            nseg += 1
            if nseg > 200000:
                raise RuntimeError("too many contact events")
            events = [
                _delta_event(
                    model, a, HYST if in_contact[a] else 0.0, -1 if in_contact[a] else 1, True
                )
                for a in range(model.nc)
            ]
            dm, act = dminus.copy(), in_contact.copy()
            sol = solve_ivp(
                lambda t, y: model.evaluate(t, y, dm, act)[0],
                (t0, T),
                y,
                method=method,
                t_eval=grid[len(ys) :],
                events=events or None,
                rtol=rtol,
                atol=atol,
                max_step=max_step,
            )
            if sol.status < 0:
                raise RuntimeError(sol.message)
            nfev, njev = nfev + sol.nfev, njev + sol.njev
            if len(sol.t):  # (scipy returns a plain [] when no t_eval point was reached)
                ys += list(sol.y.T)
                ctx += [(dm, act)] * len(sol.t)
                for tp, yp in zip(sol.t, sol.y.T):
                    check_free(tp, yp, act)
            if sol.status != 1:
                break
            hits = [(te[0], a) for a, te in enumerate(sol.t_events) if len(te)]
            t0, a = min(hits)
            y = sol.y_events[a][0]
            check_free(t0, y, act)
            in_contact[a] = not in_contact[a]
            if in_contact[a]:
                dd = model.contact(model.cj[a], y[:9], y[9:18], np.zeros(9), 1.0)["ddelta"]
                dminus[a] = max(dd, model.v_min)
                onsets[a] += 1
    errstate.__exit__(None, None, None)
    wall, n_eval = time.perf_counter() - t_wall, model.n_eval
    Y = np.array(ys)
    out = {k: np.zeros(npts) for k in ("slider_a", "crank_torque")}
    out.update(t=grid, crank_angle=np.degrees(Y[:, 2]), slider_x=Y[:, 6], slider_v=Y[:, 15], y=Y)
    for j in model.ij:
        out[j + "_reaction"] = np.zeros(npts)
    for j in model.cj:
        for key in (
            "ecc_x",
            "ecc_y",
            "delta",
            "penetration",
            "normal_force",
            "friction_force",
            "slip_velocity",
            "friction_state",
        ):
            out[f"{j}_{key}"] = np.zeros(npts)
    free_penetration = np.zeros(model.nc)  # sharp: max delta > 0 at samples in free flight
    for p in range(npts):
        _, info = model.evaluate(grid[p], Y[p], *ctx[p])
        if ctx[p][1] is not None:
            for a, ci in enumerate(info["contacts"]):
                if not ctx[p][1][a]:
                    free_penetration[a] = max(free_penetration[a], ci["delta"])
        out["slider_a"][p], out["crank_torque"][p] = info["qdd"][6], info["torque"]
        for r, j in enumerate(model.ij):
            out[j + "_reaction"][p] = np.hypot(*info["lam"][2 * r : 2 * r + 2])
        for j, ci in zip(model.cj, info["contacts"]):
            out[j + "_ecc_x"][p], out[j + "_ecc_y"][p] = ci["e_vec"]
            out[j + "_delta"][p], out[j + "_penetration"][p] = ci["delta"], max(ci["delta"], 0.0)
            out[j + "_normal_force"][p], out[j + "_friction_force"][p] = ci["FN"], ci["FT"]
            out[j + "_slip_velocity"][p], out[j + "_friction_state"][p] = ci["vT"], ci["z"]
    if track_work:
        out["drive_work"] = Y[:, -1]
        out["energy"] = np.array([model.energy(yy) for yy in Y])
    out["stats"] = dict(
        nfev=nfev,
        njev=njev,
        rhs_evals=n_eval,
        onsets=dict(zip(model.cj, onsets.tolist())),
        free_flight_penetration=dict(zip(model.cj, free_penetration.tolist())),
        wall_time=wall,
        method=method,
        mode=mode,
    )
    out["model"] = model
    return out


# ----------------------------------------------------------------------------- self-checks
MODEL_MD_IDEAL = dict(
    a_min=-19419.0,
    a_max=9696.0,
    v_peak=28.41,
    torque_max=138.52,
    O=(3004.0, 8253.0),
    A=(948.0, 6197.0),
    B=(434.0, 2719.0),
)


def check_ideal(points_per_revolution=3600, assert_ok=True):
    """Ideal joints, 5000 rpm, no gravity: docs/model.md §6 numbers, closed form, torque sign by energy."""
    r = simulate(
        (), 5000, 1, points_per_revolution, mode="sharp", rtol=1e-11, atol=1e-13, track_work=True
    )
    cf = ideal_closed_form(np.radians(r["crank_angle"]), 5000 * np.pi / 30)
    dE = r["energy"] - r["energy"][0]  # kinetic energy change (no gravity, no contact)
    res = dict(
        a_min=r["slider_a"].min(),
        a_max=r["slider_a"].max(),
        v_peak=np.abs(r["slider_v"]).max(),
        torque_min=r["crank_torque"].min(),
        torque_max=r["crank_torque"].max(),
        **{j: (r[j + "_reaction"].min(), r[j + "_reaction"].max()) for j in "OAB"},
        closed_form_err=dict(
            x=np.abs(cf["x"] - r["slider_x"]).max(),
            v=np.abs(cf["v"] - r["slider_v"]).max(),
            a=np.abs(cf["a"] - r["slider_a"]).max(),
        ),
        work_minus_dKE=np.abs(r["drive_work"] - dE).max(),
        work_plus_dKE=np.abs(r["drive_work"] + dE).max(),
        max_dKE=np.abs(dE).max(),
    )
    if assert_ok:
        ref = MODEL_MD_IDEAL
        assert abs(res["a_min"] - ref["a_min"]) < 1 and abs(res["a_max"] - ref["a_max"]) < 1
        assert abs(res["v_peak"] - ref["v_peak"]) < 0.01
        assert abs(res["torque_max"] - ref["torque_max"]) < 0.01
        assert abs(res["torque_min"] + ref["torque_max"]) < 0.01
        for j in "OAB":
            assert np.allclose(res[j], ref[j], atol=1.0), (j, res[j])
        assert res["closed_form_err"]["x"] < 1e-9 and res["closed_form_err"]["a"] < 1e-3
        assert res["work_minus_dKE"] < 1e-6 * res["max_dKE"]  # tau > 0: motor does work
        assert res["work_plus_dKE"] > 0.5 * res["max_dKE"]  # the opposite sign would fail
    return res


def check_energy(
    mode="sharp",
    method=None,
    rtol=1e-10,
    revolutions=1.0,
    friction=None,
    assert_ok=True,
    joints=("B",),
    **options,
):
    """Clearance at B (or ``joints``), c = 0.5 mm, c_e = 1: E(t) - E(0) = drive work
    (frictionless); with friction the difference W - dE (dissipation) must be >= 0 and
    non-decreasing.  ``options``: more ``simulate`` arguments (gravity, clearance, journal_body)."""
    r = simulate(
        joints,
        5000,
        revolutions,
        360,
        mode=mode,
        method=method,
        rtol=rtol,
        atol=rtol * 1e-3,
        restitution=1.0,
        friction=friction,
        track_work=True,
        **options,
    )
    diss = r["drive_work"] - (r["energy"] - r["energy"][0])
    res = dict(
        max_abs_error=np.abs(diss).max(),
        max_drive_work=np.abs(r["drive_work"]).max(),
        final_dissipation=diss[-1],
        min_dissipation_increment=np.diff(diss).min(),
        onsets=sum(r["stats"]["onsets"].values()),
        peak_normal_force=max(r[j + "_normal_force"].max() for j in joints),
    )
    if assert_ok:
        assert res["onsets"] > 5
        if friction is None:
            assert res["max_abs_error"] < 1e-5 * res["max_drive_work"], res
        else:
            assert res["final_dissipation"] > 0 and res["min_dissipation_increment"] > -1e-4, res
    return res


def check_small_clearance(clearance=1e-6, mode="sharp", revolutions=2, rtol=1e-8, assert_ok=True):
    """Clearance at B of 1 µm: slider motion and torque approach the ideal ones (2nd revolution)."""
    ide = simulate((), 5000, revolutions, 360, mode="sharp", rtol=1e-11, atol=1e-13)
    r = simulate(
        ("B",), 5000, revolutions, 360, mode=mode, rtol=rtol, atol=rtol * 1e-3, clearance=clearance
    )
    sel = r["t"] >= r["t"][-1] / revolutions * (revolutions - 1)

    def rms(x):
        return np.sqrt(np.mean(x[sel] ** 2))

    res = dict(
        max_dx=np.abs(r["slider_x"] - ide["slider_x"])[sel].max(),
        max_dv=np.abs(r["slider_v"] - ide["slider_v"])[sel].max(),
        rel_rms_da=rms(r["slider_a"] - ide["slider_a"]) / rms(ide["slider_a"]),
        rel_rms_dtorque=rms(r["crank_torque"] - ide["crank_torque"]) / rms(ide["crank_torque"]),
        rel_rms_dforce=rms(r["B_normal_force"] - ide["B_reaction"]) / rms(ide["B_reaction"]),
        max_penetration=r["B_penetration"].max(),
        onsets=r["stats"]["onsets"]["B"],
    )
    if assert_ok:
        assert res["max_dx"] < 10 * clearance + 5e-6 and res["rel_rms_dtorque"] < 0.05, res
    return res


def check_smooth_vs_sharp(
    t_end=2e-3,
    window=0.5e-3,
    joints=("B",),
    rtol=1e-11,
    smooth_method="DOP853",
    widths=(1e-7,),
    assert_ok=True,
):
    """Max |e_smooth - e_sharp| (µm) of each joint's eccentricity vector per time window, at tight
    tolerances, for each smoothing width (w_delta = w_m = width, w_factor = 1e4 * width)."""
    rev = t_end * 5000 / 60
    kw = dict(
        rpm=5000,
        revolutions=rev,
        points_per_revolution=round(t_end / 2e-6) / rev,
        rtol=rtol,
        atol=rtol * 1e-3,
    )
    sharp = simulate(joints, mode="sharp", **kw)
    t, edges = sharp["t"], np.arange(0.0, t_end + 1e-12, window)
    wins = list(zip(edges[:-1], edges[1:]))
    res = dict(
        windows_ms=[(a * 1e3, b * 1e3) for a, b in wins], sharp_onsets=sharp["stats"]["onsets"]
    )
    for w in widths:
        sm = simulate(
            joints, mode="smooth", method=smooth_method, w_delta=w, w_m=w, w_factor=1e4 * w, **kw
        )
        res[w] = dict(onsets=sm["stats"]["onsets"])
        for j in joints:
            d = 1e6 * np.hypot(
                sm[j + "_ecc_x"] - sharp[j + "_ecc_x"], sm[j + "_ecc_y"] - sharp[j + "_ecc_y"]
            )
            res[w][j + "_max_diff_um"] = [d[(t > a) & (t <= b)].max() for a, b in wins]
    if assert_ok and 1e-7 in widths:
        worst = max(v[0] for k, v in res[1e-7].items() if k.endswith("_um"))
        assert worst < 1.0, res  # < 1 µm in the first window (later ones amplify, §5b)
    return res


def timings(joint_sets=(("B",), ("O", "A", "B")), methods=(("smooth", "Radau"),), rtol=1e-6):
    """Wall time and evaluation counts, 2 revolutions at 5000 rpm."""
    out = {}
    for js in joint_sets:
        for mode, method in methods:
            s = simulate(js, 5000, 2, 360, mode=mode, method=method, rtol=rtol, atol=1e-9)["stats"]
            out[("".join(js), mode, method)] = s
    return out


if __name__ == "__main__":
    for name, fn in [
        ("ideal", check_ideal),
        ("energy sharp", check_energy),
        ("energy smooth Radau", lambda: check_energy("smooth", "Radau", 1e-8)),
        ("energy sharp, Coulomb mu=0.1", lambda: check_energy(friction=("coulomb", 0.1, 1e-4))),
        ("small clearance", check_small_clearance),
        ("smooth vs sharp", lambda: check_smooth_vs_sharp(widths=(1e-7, 1e-8, 1e-9))),
    ]:
        print(name, fn())
    for key, s in timings(
        methods=(("smooth", "Radau"), ("smooth", "DOP853"), ("sharp", "DOP853"))
    ).items():
        print(key, s)
