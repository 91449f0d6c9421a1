"""The paper's early-z cost model (note 001 §2.2 and §2.6): Eqs. 1–9 and their normalised forms.

Symbols (the paper's), with the names the functions take:

========  ===============  ==========================================================================
symbol    argument         meaning
========  ===============  ==========================================================================
F         ``fragments``    fragments the slices generate (every slice fragment)
F_s       ``setup``        fragments of a generic two-pass renderer's first (z-setup) pass
F_c       ``shaded``       fragments that reach the complex shader (F'_c for iSBVR)
F_t, F_p  ``surface_t``,   fragments of Φ_t's back faces and Φ_p's front faces (iSBVR's init passes)
          ``surface_p``
T_s       ``t_simple``     time per fragment of the simple (z-setup) shader
T_z       ``t_culled``     time per fragment the early depth test discards
T_c       ``t_complex``    time per fragment of the complex (volume) shader
α, α'     ``alpha``        culling rate (F − F_c) / F
γ         ``gamma``        simple-to-complex shader time T_s / T_c
φ         ``phi``          init fragments over all fragments (F_t + F_p) / F
δ         (returned)       speed-up over one pass running the complex shader on every fragment
========  ===============  ==========================================================================

The generic two-pass renderer (Eqs. 1–6: a per-slice opacity pass sets the depth, F_s = F and
T_z ≈ T_s) pays off only above the culling rate γ / (1 − γ) and never beats 1 / (2γ); iSBVR (Eqs. 7–9)
draws a few surface fragments instead, so its ceiling is 1 / γ.

Every function takes numbers or NumPy arrays (broadcast together, e.g. bootstrap draws of the times)
and returns a float for scalar inputs, an array otherwise (``numpy.ndarray``).
"""

import numpy as np

from core.errors import InputError

WHAT = {"fragments": "a fragment count (F)", "setup": "a fragment count (F_s)", "shaded": "a fragment count (F_c)",
        "surface_t": "a fragment count (F_t)", "surface_p": "a fragment count (F_p)",
        "t_simple": "a time per fragment (T_s)", "t_culled": "a time per fragment (T_z)",
        "t_complex": "a time per fragment (T_c)", "gamma": "a shader time ratio T_s / T_c (γ)",
        "phi": "a share of init fragments (φ)", "speedup": "a speed-up (δ)"}


def _values(value, name, what=None, *, positive=False):
    """``value`` as a float array: finite and at least 0 (above 0 with ``positive``), else an error naming it."""
    what = what or WHAT[name]
    if isinstance(value, (bool, np.bool_, str)):
        raise InputError(f"{name}: expected {what} (a number or an array of numbers), got {value!r}")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected {what} (a number or an array of numbers), got {value!r}") from None
    if not np.isfinite(array).all():
        raise InputError(f"{name}: expected finite {what}, got {value!r}")
    if positive and (array <= 0).any():
        raise InputError(f"{name}: expected {what} > 0, got {value!r}")
    if (array < 0).any():
        raise InputError(f"{name}: expected {what} >= 0, got {value!r}")
    return array


def _fraction(value, name, what):
    array = _values(value, name, what)
    if (array > 1).any():
        raise InputError(f"{name}: expected {what} in [0, 1], got {value!r}")
    return array


def _shaded(fragments, shaded, *, positive=True):
    """``(F, F_c)`` checked: F > 0 (it divides) and 0 <= F_c <= F."""
    fragments = _values(fragments, "fragments", positive=positive)
    shaded = _values(shaded, "shaded")
    if (shaded > fragments).any():
        raise InputError(f"shaded: the fragments that reach the complex shader (F_c) cannot exceed the fragments "
                         f"generated (F): got F_c {shaded.tolist()} against F {fragments.tolist()}")
    return fragments, shaded


def _gamma(gamma):
    return _values(gamma, "gamma", positive=True)


def _alpha_gamma(alpha, gamma):
    """``(α, γ)`` checked: α a culling rate in [0, 1], γ > 0."""
    return _fraction(alpha, "alpha", "a culling rate (α)"), _gamma(gamma)


def _out(array):
    """A float for a scalar result, the array otherwise."""
    return float(array) if np.ndim(array) == 0 else array


def culling_rate(fragments, shaded):
    """The culling rate α = (F − F_c) / F in [0, 1]: the share of fragments kept from the complex shader (F > 0,
    0 <= F_c <= F)."""
    fragments, shaded = _shaded(fragments, shaded)
    return _out((fragments - shaded) / fragments)


def shader_ratio(t_simple, t_complex):
    """γ = T_s / T_c (both > 0, any one unit): the paper's "simple shader speed-up"."""
    return _out(_values(t_simple, "t_simple", positive=True) / _values(t_complex, "t_complex", positive=True))


def surface_share(fragments, surface_t, surface_p):
    """φ = (F_t + F_p) / F: iSBVR's init-pass fragments over the slices' fragments (F > 0)."""
    fragments = _values(fragments, "fragments", positive=True)
    return _out((_values(surface_t, "surface_t") + _values(surface_p, "surface_p")) / fragments)


def two_pass_time(*, fragments, setup, shaded, t_simple, t_culled, t_complex):
    """Eq. 1: T_2pass = F_s·T_s + (F − F_c)·T_z + F_c·T_c, in the unit of the times per fragment (F > 0,
    0 <= F_c <= F, the rest >= 0)."""
    fragments, shaded = _shaded(fragments, shaded)
    setup, t_simple, t_culled, t_complex = (_values(value, name) for name, value in (
        ("setup", setup), ("t_simple", t_simple), ("t_culled", t_culled), ("t_complex", t_complex)))
    return _out(setup * t_simple + (fragments - shaded) * t_culled + shaded * t_complex)


def two_pass_speedup(*, fragments, setup, shaded, t_simple, t_culled, t_complex):
    """Eq. 2: δ = F·T_c / T_2pass, the speed-up over one pass shading every fragment (:func:`two_pass_time`'s
    arguments, T_c > 0)."""
    _values(t_complex, "t_complex", positive=True)
    time = two_pass_time(fragments=fragments, setup=setup, shaded=shaded, t_simple=t_simple, t_culled=t_culled,
                         t_complex=t_complex)
    return _out(np.asarray(fragments, float) * np.asarray(t_complex, float) / np.asarray(time))


def per_slice_time(*, fragments, shaded, t_simple, t_complex):
    """Eq. 3: T_2pass = F·T_s + (F − F_c)·T_s + F_c·T_c, per-slice two-pass slicing (F_s = F, T_z = T_s)."""
    return two_pass_time(fragments=fragments, setup=fragments, shaded=shaded, t_simple=t_simple, t_culled=t_simple,
                         t_complex=t_complex)


def per_slice_speedup(*, fragments, shaded, t_simple, t_complex):
    """Eq. 4: δ = F·T_c / (F·T_s + (F − F_c)·T_s + F_c·T_c) (T_c > 0)."""
    return two_pass_speedup(fragments=fragments, setup=fragments, shaded=shaded, t_simple=t_simple,
                            t_culled=t_simple, t_complex=t_complex)


def normalised_speedup(alpha, gamma):
    """Eq. 5: δ = 1 / (αγ + 1 − α + γ), Eq. 4 in the culling rate α in [0, 1] and the shader ratio γ > 0."""
    alpha, gamma = _alpha_gamma(alpha, gamma)
    return _out(1.0 / (alpha * gamma + 1.0 - alpha + gamma))


def pays_off(alpha, gamma):
    """Eq. 6: whether per-slice two-pass rendering beats one pass, (1 − γ)(α + 1) > 1 (that is, δ > 1); a bool, or
    an array of them."""
    alpha, gamma = _alpha_gamma(alpha, gamma)
    result = (1.0 - gamma) * (alpha + 1.0) > 1.0
    return bool(result) if np.ndim(result) == 0 else result


def break_even_culling(gamma):
    """The culling rate above which per-slice two-pass rendering pays off (Eq. 6): α > γ / (1 − γ), γ > 0.

    The paper's example: γ = 0.2 needs α > 25 %. From γ = 1/2 on the rate is 1 or more, which no
    renderer reaches; from γ = 1 on nothing pays off and the result is infinite.
    """
    gamma = _gamma(gamma)
    with np.errstate(divide="ignore"):
        return _out(np.where(gamma < 1.0, gamma / np.where(gamma < 1.0, 1.0 - gamma, 1.0), np.inf))


def per_slice_ceiling(gamma):
    """The most per-slice two-pass rendering can gain, Eq. 5 as α → 1: 1 / (2γ), γ > 0."""
    return _out(1.0 / (2.0 * _gamma(gamma)))


def isbvr_init_time(*, surface_t, surface_p, t_simple):
    """Eq. 7: T_a = F_t·T_s + F_p·T_s, the depth-init passes over Φ_t's back and Φ_p's front faces (all >= 0)."""
    surface_t, surface_p, t_simple = (_values(value, name) for name, value in (
        ("surface_t", surface_t), ("surface_p", surface_p), ("t_simple", t_simple)))
    return _out((surface_t + surface_p) * t_simple)


def isbvr_volume_time(*, fragments, shaded, t_simple, t_complex):
    """Eq. 8: T_m = (F − F'_c)·T_s + F'_c·T_c, the volume pass with culled fragments at T_s (T_z ≈ T_s)."""
    return two_pass_time(fragments=fragments, setup=0.0, shaded=shaded, t_simple=t_simple, t_culled=t_simple,
                         t_complex=t_complex)


def isbvr_speedup(*, fragments, surface_t, surface_p, shaded, t_simple, t_complex):
    """Eq. 9: δ = F·T_c / (F_t·T_s + F_p·T_s + (F − F'_c)·T_s + F'_c·T_c), iSBVR over Basic slicing.

    F'_c are the fragments that pass the depth test into the volume shader (0 <= F'_c <= F), T_c > 0.
    """
    _values(t_complex, "t_complex", positive=True)
    init = isbvr_init_time(surface_t=surface_t, surface_p=surface_p, t_simple=t_simple)
    volume = isbvr_volume_time(fragments=fragments, shaded=shaded, t_simple=t_simple, t_complex=t_complex)
    return _out(np.asarray(fragments, float) * np.asarray(t_complex, float) / (np.asarray(init) + np.asarray(volume)))


def isbvr_normalised_speedup(alpha, phi, gamma):
    """Eq. 9 normalised: δ = 1 / (γ(φ + α') + 1 − α'), with α' = (F − F'_c) / F in [0, 1], φ >= 0 and γ > 0."""
    alpha = _fraction(alpha, "alpha", "a culling rate (α')")
    phi = _values(phi, "phi")
    gamma = _gamma(gamma)
    return _out(1.0 / (gamma * (phi + alpha) + 1.0 - alpha))


def isbvr_ceiling(gamma):
    """The most iSBVR can gain, Eq. 9 as α' → 1 and φ → 0: 1 / γ (twice the per-slice ceiling), γ > 0."""
    return _out(1.0 / _gamma(gamma))


def implied_culling(speedup, *, gamma=0.0, phi=0.0):
    """The culling rate α' a speed-up δ > 0 implies under Eq. 9: α' = (1 + γφ − 1/δ) / (1 − γ), γ in [0, 1),
    φ >= 0.

    With ``gamma`` and ``phi`` 0 (free culled fragments, no init passes) it is 1 − 1/δ, the least
    culling that can explain δ (note 001 §3.1's "implied culling rate"). Outside [0, 1] where no culling
    rate gives δ with these γ and φ.
    """
    speedup = _values(speedup, "speedup", positive=True)
    gamma = _values(gamma, "gamma")
    if (gamma >= 1).any():
        raise InputError(f"gamma: expected a shader time ratio (γ) below 1, got {gamma.tolist()}; "
                         "with γ >= 1 culling cannot change the time and no rate is implied")
    phi = _values(phi, "phi")
    return _out((1.0 + gamma * phi - 1.0 / speedup) / (1.0 - gamma))
