"""Hydrodynamic film of a lubricated revolute clearance joint (docs/model.md §3b) [lit, ours].

Source: the journal-bearing forces used by Flores, Ambrósio, Claro & Lankarani, "Dynamics of
mechanical systems including joints with clearance and lubrication", Mech. Mach. Theory 41 (2006)
(after Pinkus & Sternlicht, *Theory of Hydrodynamic Lubrication*, McGraw-Hill 1961): the
short-bearing (Ocvirk) and long-bearing (Sommerfeld) solutions of Reynolds' equation over a
half film (Gümbel), with squeeze terms. What is reconstructed here [ours]: where the half film
lies when the journal also moves radially, the Cartesian evaluation, the Petroff torque and the
blend with the dry contact law. Equations as implemented:

Geometry. e⃗ = r_journal − r_bearing, ε⃗ = e⃗/c, ε = ‖ε⃗‖, n = ε⃗/ε, t = n turned by +90°. The
film angle θ is measured counterclockwise from −n (the widest gap): h = c(1 + ε cos θ), and the
journal's surface normal there is u(θ) = −cos θ n − sin θ t.

Rates. ε̇ = nᵀė⃗/c; the line of centres turns at γ̇ = tᵀė⃗/(c ε); wedge speed
w = ω_J + ω_B − 2γ̇ (absolute angular velocities), so X = w ε = (ω_J + ω_B) ε − 2 tᵀė⃗/c and
Y = 2ε̇ are finite at ε = 0.

Reynolds' equation in the frame of the line of centres, x = Rθ:
∂x(h³ ∂x p) + ∂z(h³ ∂z p) = 6μ R w ∂x h + 12μ ∂t h, with ∂t h = c ε̇ cos θ.

- Short bearing (drop ∂x, p = 0 at z = ±L/2): p = 3μ/(c² D³) (L²/4 − z²)(X sin θ − Y cos θ),
  D = 1 + ε cos θ. X sin θ − Y cos θ = A sin(θ − a) with A = √(X² + Y²), (cos a, sin a) = (X, Y)/A:
  the pressure is positive exactly on the half film a < θ < a + π, and the force is integrated
  there only (no suction, even for fast separation).
- Long bearing (drop ∂z): h³ p' = 6μR²c (X cos θ + Y sin θ + C), with p = 0 at both ends of the
  same half film a < θ < a + π (C from ∫p' dθ = 0); p' changes sign once inside, so p > 0 there.
  With Y = 0 the film is 0 < θ < π and these are the Pinkus–Sternlicht/Flores forms.

Force on the journal F = R ∫∫ p (cos θ n + sin θ t) dθ dz = F_n n + F_t t, with the integrals
over the half film (each in closed form through the Sommerfeld substitution
1 + ε cos θ = (1 − ε²)/(1 − ε cos ψ), ``_half_film_integrals``):

- short, K = μ R L³/(2c²): F_n = K (X S_sc − Y C_cc), F_t = K (X S_ss − Y S_sc);
- long, K = 6μ R³ L/c², C = −(X I_c + Y I_s)/I_1:
  F_n = −K (X S_sc + Y S_ss + C I_s), F_t = K (X C_cc + Y S_sc + C I_c);

where I_1 = ∫D⁻³, I_c = ∫cos θ D⁻³, I_s = ∫sin θ D⁻³, S_sc = ∫sin θ cos θ D⁻³, C_cc = ∫cos²θ D⁻³,
S_ss = ∫sin²θ D⁻³ over a < θ < a + π. With Y = 0 (a = 0) the short bearing gives
F_n = −2Kwε²/(1−ε²)², F_t = πKwε/(2(1−ε²)^{3/2}), so the attitude angle of a steady load obeys
Ocvirk's tan φ = F_t/(−F_n) = π√(1−ε²)/(4ε). At ε = 0 both give F = −π K ė⃗/c (short) whatever
n is, so the Cartesian form is continuous there; a double ``where`` keeps gradients finite.

Petroff torque (option): Couette shear over the full film, on the journal
T = −2π μ R³ L (ω_J − ω_B)/(c √(1 − ε²)), the opposite on the bearing.

Blend with dry contact [ours]: the film acts with weight 1 − s, s = smooth_step(ε − ε₀, Δ) (C¹
cubic, 0 below ε₀, 1 from ε₀ + Δ ≤ 1); inside the blend the film is evaluated at a saturated
ratio ε_f = ε₀ + Δ tanh((min(ε, ε₀ + Δ) − ε₀)/Δ) (= ε below ε₀, C² there), so the forces stay
bounded however stiff the film is. The dry contact law and friction act once the journal
reaches the wall (ε ≥ 1, where s = 1), so the total force is continuous through the switch.
"""

import math

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core._checks import check_open_interval, check_positive, is_concrete
from .._core._errors import ModelError
from .._core._smooth import safe_norm, smooth_step

LUBRICATION_THEORIES = ("short", "long")
"""Bearing theories: ``"short"`` (Ocvirk, L/D ≲ 0.5) and ``"long"`` (Sommerfeld, L/D ≳ 2)."""


def _array(x):
    return jnp.asarray(x, dtype=float)


class Lubrication(eqx.Module):
    """Hydrodynamic lubricant film of a revolute clearance joint (``ClearanceJoint.lubrication``).

    Attributes:
        viscosity: dynamic viscosity μ of the lubricant, Pa s (> 0).
        length: bearing length L, m (> 0).
        theory: ``"short"`` (Ocvirk) or ``"long"`` (Sommerfeld) bearing (static).
        transition_eccentricity: ε₀ in (0, 1): the film alone acts below it.
        transition_width: Δ > 0 with ε₀ + Δ ≤ 1: the film fades out over ε₀ < ε < ε₀ + Δ.
        petroff: add the Petroff shear torque (static).
    """

    viscosity: Float[Array, ""] = eqx.field(converter=_array)
    length: Float[Array, ""] = eqx.field(converter=_array)
    theory: str = eqx.field(static=True, default="short")
    transition_eccentricity: Float[Array, ""] = eqx.field(converter=_array, default=0.9)
    transition_width: Float[Array, ""] = eqx.field(converter=_array, default=0.1)
    petroff: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        owner = "Lubrication"
        if self.theory not in LUBRICATION_THEORIES:
            raise ModelError(
                f"{owner}: theory must be one of {', '.join(map(repr, LUBRICATION_THEORIES))}, got {self.theory!r}."
            )
        if not isinstance(self.petroff, bool):
            raise ModelError(f"{owner}: petroff must be true or false, got {self.petroff!r}.")
        check_positive(owner, "viscosity", self.viscosity, "Pa s")
        check_positive(owner, "length", self.length, "m")
        check_positive(owner, "transition_width", self.transition_width)
        e0, width = self.transition_eccentricity, self.transition_width
        check_open_interval(
            owner,
            "transition_eccentricity (ε₀)",
            e0,
            0.0,
            1.0,
            "the film acts alone below it and the wall is at 1, e.g. 0.9",
        )
        if is_concrete(e0) and is_concrete(width) and float(e0) + float(width) > 1.0 + 1e-12:
            raise ModelError(
                f"{owner}: transition_eccentricity + transition_width must be at most 1 (the wall), "
                f"got {float(e0)} + {float(width)}; lower one of them."
            )


class FilmForce(eqx.Module):
    """The film's action on the journal at an instant (the bearing gets the opposite).

    Attributes:
        force: F on the journal (global components), N, already weighted by ``weight``.
        torque: Petroff torque on the journal, N m (0 without ``petroff``), weighted.
        weight: 1 − s, the film's share of the blend (1 below ε₀, 0 from ε₀ + Δ).
    """

    force: Float[Array, "2"]
    torque: Float[Array, ""]
    weight: Float[Array, ""]


def _safe_unit(v, norm):
    nonzero = norm > 0
    return jnp.where(nonzero, v / jnp.where(nonzero, norm, 1.0), jnp.array([1.0, 0.0]))


def _half_film_integrals(eps, ca, sa):
    """(I_1, I_c, I_s, S_sc, C_cc, S_ss): ∫ f(θ)/(1 + ε cos θ)³ dθ over a < θ < a + π for
    f = 1, cos θ, sin θ, sin θ cos θ, cos² θ, sin² θ, with (cos a, sin a) = (ca, sa).

    Sommerfeld substitution 1 + ε cos θ = (1 − ε²)/(1 − ε cos ψ), dθ/(1 + ε cos θ)³ =
    (1 − ε cos ψ)² dψ/(1 − ε²)^{5/2}, cos ψ = (cos θ + ε)/(1 + ε cos θ),
    sin ψ = √(1 − ε²) sin θ/(1 + ε cos θ); ψ(θ) = θ − 2 atan(β sin θ/(1 + β cos θ)),
    β = ε/(1 + √(1 − ε²)), so ψ(a + π) − ψ(a) = π + 2 atan(β sin a/(1 − β cos a))
    + 2 atan(β sin a/(1 + β cos a)). Every integrand becomes a trigonometric polynomial in ψ.
    """
    q = 1.0 - eps * eps
    root = jnp.sqrt(q)
    beta = eps / (1.0 + root)
    dpsi = (
        math.pi
        + 2.0 * jnp.arctan(beta * sa / (1.0 - beta * ca))
        + 2.0 * jnp.arctan(beta * sa / (1.0 + beta * ca))
    )

    def psi_point(c, s):
        d = 1.0 + eps * c
        return (c + eps) / d, root * s / d

    cpa, spa = psi_point(ca, sa)
    cpb, spb = psi_point(-ca, -sa)
    d_sin = spb - spa
    d_cos = cpb - cpa
    d_sin2 = 2.0 * (spb * cpb - spa * cpa)
    d_sinsq = spb * spb - spa * spa
    q52 = q * q * root
    i1 = ((1.0 + 0.5 * eps * eps) * dpsi - 2.0 * eps * d_sin + 0.25 * eps * eps * d_sin2) / q52
    ic = ((1.0 + eps * eps) * d_sin - 1.5 * eps * dpsi - 0.25 * eps * d_sin2) / q52
    i_s = (-d_cos - 0.5 * eps * d_sinsq) / (q * q)
    ssc = (0.5 * d_sinsq + eps * d_cos) / (q * q)
    ccc = ((0.5 + eps * eps) * dpsi + 0.25 * d_sin2 - 2.0 * eps * d_sin) / q52
    sss = (0.5 * dpsi - 0.25 * d_sin2) / (q * root)
    return i1, ic, i_s, ssc, ccc, sss


def film_components(theory: str, eps, wedge, squeeze, viscosity, length, radius, clearance):
    """(F_n, F_t): film force on the journal along n and t, N (module docstring).

    Args:
        theory: ``"short"`` or ``"long"``.
        eps: eccentricity ratio ε in [0, 1).
        wedge: X = w ε, rad/s (w = ω_J + ω_B − 2γ̇).
        squeeze: Y = 2ε̇, 1/s.
        viscosity, length, radius, clearance: μ (Pa s), L, R, c (m).
    """
    amplitude = safe_norm(jnp.stack([wedge, squeeze]))
    unit = _safe_unit(jnp.stack([wedge, squeeze]), amplitude)
    ca, sa = unit[0], unit[1]
    i1, ic, i_s, ssc, ccc, sss = _half_film_integrals(eps, ca, sa)
    x, y = wedge, squeeze
    if theory == "short":
        k = viscosity * radius * length**3 / (2.0 * clearance**2)
        return k * (x * ssc - y * ccc), k * (x * sss - y * ssc)
    if theory == "long":
        k = 6.0 * viscosity * radius**3 * length / clearance**2
        const = -(x * ic + y * i_s) / i1
        return -k * (x * ssc + y * sss + const * i_s), k * (x * ccc + y * ssc + const * ic)
    raise ValueError(f"theory must be one of {', '.join(LUBRICATION_THEORIES)}, got {theory!r}.")


def film_force(
    lubrication: Lubrication,
    eccentricity_vector,
    eccentricity_rate,
    journal_omega,
    bearing_omega,
    radius,
    clearance,
) -> FilmForce:
    """The film's force and torque on the journal, blended out towards the wall (module docstring).

    Args:
        lubrication: the film's parameters.
        eccentricity_vector: e⃗ = r_journal − r_bearing, m, shape (2,).
        eccentricity_rate: ė⃗, m/s, shape (2,).
        journal_omega, bearing_omega: absolute angular velocities ω_J, ω_B, rad/s.
        radius: journal radius R, m. clearance: c, m.

    Returns:
        ``FilmForce`` (force on the journal, Petroff torque on the journal, film weight 1 − s).
    """
    lub = lubrication
    ratio = eccentricity_vector / clearance
    eps = safe_norm(ratio)
    n = _safe_unit(ratio, eps)
    t = jnp.stack([-n[1], n[0]])
    rate = eccentricity_rate / clearance
    e0, width = lub.transition_eccentricity, lub.transition_width
    # saturated film ratio ε_f (= ε below ε₀); the double where keeps ε_f/ε finite at ε = 0
    above = eps > e0
    capped = jnp.minimum(eps, e0 + width)
    saturated = e0 + width * jnp.tanh((jnp.where(above, capped, e0) - e0) / width)
    eps_f = jnp.where(above, saturated, eps)
    scale = jnp.where(above, eps_f / jnp.where(above, eps, 1.0), 1.0)
    wedge = scale * ((journal_omega + bearing_omega) * eps - 2.0 * (t @ rate))
    squeeze = 2.0 * (n @ rate)
    fn, ft = film_components(
        lub.theory, eps_f, wedge, squeeze, lub.viscosity, lub.length, radius, clearance
    )
    weight = 1.0 - smooth_step(eps - e0, width)
    torque = jnp.zeros_like(eps)
    if lub.petroff:
        torque = (
            -2.0
            * math.pi
            * lub.viscosity
            * radius**3
            * lub.length
            * (journal_omega - bearing_omega)
            / (clearance * jnp.sqrt(1.0 - eps_f * eps_f))
        )
    return FilmForce(force=weight * (fn * n + ft * t), torque=weight * torque, weight=weight)
