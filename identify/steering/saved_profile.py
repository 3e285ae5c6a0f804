"""An identified steering model written into a ship profile's per-sample form (``steering --save-profile``).

A profile's sway and yaw rows are per-sample increments nu(k+1) - nu(k) = Phi(k)^T theta (Ljungberg 2022,
eq. (3.60)); at the trial speed V, straight ahead, their linear part in [v, r, delta] is

    [v, r](k+1) - [v, r](k) = F [v, r](k) + g delta(k),

which the identified continuous model (A, b) in [v, r] gives exactly as F = e^{A Ts} - I and
g = int_0^Ts e^{A s} ds b (zero-order hold, the profile's sample time Ts). One coefficient per (row, variable)
— the row's dominant term linear in that variable alone, e.g. ``u_r*r`` in yaw for r — is changed so that the
profile's linearisation equals (F, g); every other coefficient (surge, the nonlinear terms) is the base
profile's.

What (A, b) is depends on the model fitted:

- ``state-space``: the identified [v, r] matrices (3.1) themselves: all six linear sway/yaw coefficients.
- ``nomoto2``: r/delta = K (1 + T3 s) / ((1 + T1 s)(1 + T2 s)) fixes four numbers (trace and determinant
  of A, the numerator b_r s + a_rv b_v - a_vv b_r); the base profile's sway coupling to r and rudder
  (a_vr, b_v) are kept and a_vv, a_rv, a_rr, b_r solved from them (one quadratic in a_vv, the root nearest
  the base's). The sway row's v term is then identified only through the yaw response it produces.
- ``nomoto1``: K and T1 = T from the identification; T2 the base profile's fast mode and T3 = T2, so that the
  pole and zero cancel and r/delta is exactly K / (1 + T s) (a first-order fit says nothing of the fast mode,
  and a fast mode with its own zero would change the first-order fit of the saved profile); then as ``nomoto2``.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.linalg import logm

from identify.steering.models import discretize
from primitives.errors import UserError
from primitives.ship import PROFILE_DIR, ShipProfile
from primitives.simulate import model_signals

VARS = ("v", "r", "delta")
ROWS = ("sway", "yaw")


@dataclass(frozen=True)
class Linearisation:
    """The per-sample linear part of a profile's sway and yaw rows at (u = V, v = r = delta = 0, steady n):
    F (2, 2) on [v, r], g (2,) on delta, and each term's regressor slope d Phi_j / d x (row, term, variable)."""

    F: np.ndarray
    g: np.ndarray
    slopes: list[np.ndarray]  # per row (sway, yaw): (n_terms, 3) slopes on v, r, delta


def linearise(profile: ShipProfile, theta: np.ndarray, V: float, n_rps: float) -> Linearisation:
    """Central differences of the sway and yaw regressors about the straight run at speed ``V``."""
    eps = 1e-6 * max(V, 1.0)
    slopes = [np.zeros((len(profile.model_terms[i + 1]), 3)) for i in range(2)]
    for j, x in enumerate(VARS):
        ends = []
        for s in (1.0, -1.0):
            nu = np.array([V, s * eps if x == "v" else 0.0, s * eps if x == "r" else 0.0])
            sig = model_signals(profile, nu, np.array(0.0), {"delta": s * eps if x == "delta" else 0.0, "n": n_rps})
            ends.append([np.asarray(profile.model.evaluate_dof(i + 1, sig), float) for i in range(2)])
        for i in range(2):
            slopes[i][:, j] = (ends[0][i] - ends[1][i]) / (2 * eps)
    lin = np.array([theta[profile.model.dof_slice(i + 1)] @ slopes[i] for i in range(2)])
    return Linearisation(lin[:, :2], lin[:, 2], slopes)


def continuous(lin: Linearisation, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """The continuous (A, b) whose zero-order-hold sampling at ``ts`` is the profile's (F, g):
    A = log(I + F) / ts, b = (e^{A ts} - I)^-1 A g."""
    Phi = np.eye(2) + lin.F
    if np.any(np.linalg.eigvals(Phi).real <= 0):
        raise UserError("the base profile's per-sample sway/yaw model has no continuous-time equivalent at this speed")
    A = np.real(logm(Phi)) / ts
    return A, np.linalg.solve(lin.F, A @ lin.g)


def nomoto_time_constants(A: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float]:
    """K [1/s], T1, T2, T3 [s] of r/delta for the [v, r] model (A, b) (Källström 1977, (3.6)); |T1| >= |T2|."""
    tr, det = float(np.trace(A)), float(np.linalg.det(A))
    lam = np.roots([1.0, -tr, det])
    if np.any(np.abs(lam.imag) > 1e-12) or np.any(lam.real == 0):
        raise UserError(
            "the base profile's linear sway/yaw model is oscillatory at this speed: no Nomoto form to take T2, T3 from"
        )
    T1, T2 = sorted((-1.0 / lam.real).tolist(), key=abs, reverse=True)  # a course-unstable ship: T1 < 0
    n0 = A[1, 0] * b[0] - A[0, 0] * b[1]
    return n0 / det, T1, T2, b[1] / n0


def yaw_matched(
    A_base: np.ndarray, b_base: np.ndarray, K: float, T1: float, T2: float, T3: float
) -> tuple[np.ndarray, np.ndarray]:
    """(A, b) with r/delta = K (1 + T3 s) / ((1 + T1 s)(1 + T2 s)) [SI], keeping the base's a_vr and b_v:
    b_r = K T3 / (T1 T2), a_rv = (K / (T1 T2) + a_vv b_r) / b_v, a_rr = tr - a_vv and a_vv a root of
    a_vv^2 - (tr - a_vr b_r / b_v) a_vv + a_vr K / (T1 T2 b_v) + det = 0 (the determinant condition)."""
    a_vr, b_v = float(A_base[0, 1]), float(b_base[0])
    if b_v == 0:
        raise UserError(
            "the base profile's sway row has no rudder force: a Nomoto fit cannot be written into it; use --model state-space"
        )
    tr, det = -(1.0 / T1 + 1.0 / T2), 1.0 / (T1 * T2)
    b_r, n0 = K * T3 * det, K * det
    roots = np.roots([1.0, -(tr - a_vr * b_r / b_v), a_vr * n0 / b_v + det])
    real = roots[np.abs(roots.imag) <= 1e-9 * max(1.0, float(np.abs(roots).max()))].real
    if len(real) == 0:
        raise UserError(
            "the identified yaw response cannot be written with the base profile's sway coupling (no real solution); "
            "use --model state-space or another base profile"
        )
    a_vv = float(real[np.argmin(np.abs(real - A_base[0, 0]))])
    A = np.array([[a_vv, a_vr], [(n0 + a_vv * b_r) / b_v, tr - a_vv]])
    return A, np.array([b_v, b_r])


def chosen_terms(profile: ShipProfile, theta: np.ndarray, lin: Linearisation) -> dict[tuple[int, int], int]:
    """For each (row, variable) the index (within the row) of the term that carries it: linear in that
    variable alone at the operating point, the largest contribution first (the base's own term for it)."""
    out = {}
    for i in range(2):
        S = lin.slopes[i]
        th = theta[profile.model.dof_slice(i + 1)]
        for j in range(3):
            others = np.delete(np.abs(S), j, axis=1).max(axis=1)
            cand = np.flatnonzero((np.abs(S[:, j]) > 0) & (others <= 1e-9 * np.abs(S[:, j])))
            if len(cand) == 0:
                raise UserError(
                    f"profile {profile.name!r}: its {ROWS[i]} row has no term linear in {VARS[j]} alone "
                    f"(e.g. '{'delta*u_r^2' if VARS[j] == 'delta' else 'u_r*' + VARS[j]}'): the identified model cannot be written into it"
                )
            out[(i, j)] = int(cand[np.argmax(np.abs(th[cand] * S[cand, j]))])
    return out


def write_linear(
    profile: ShipProfile, theta: np.ndarray, lin: Linearisation, F: np.ndarray, g: np.ndarray
) -> tuple[np.ndarray, list[tuple[str, float, float]]]:
    """``theta`` with the chosen terms changed so that the linearisation is (F, g); the changes as
    (parameter name, base value, new value)."""
    new = np.array(theta, float)
    target = np.column_stack([F, g])
    changes = []
    for (i, j), t in chosen_terms(profile, theta, lin).items():
        sl = profile.model.dof_slice(i + 1)
        row = new[sl]
        current = row @ lin.slopes[i][:, j]
        k = sl.start + t
        old = new[k]
        new[k] = old + (target[i, j] - current) / lin.slopes[i][t, j]
        changes.append((profile.parameter_names[i + 1][t], float(old), float(new[k])))
    return new, changes


def target_model(fit, lin: Linearisation, ts: float, nomoto: dict) -> tuple[np.ndarray, np.ndarray, str]:
    """The identified continuous (A, b) in [v, r] for a fit of any structure, and a line saying what came from where."""
    st = fit.structure
    A_b, b_b = continuous(lin, ts)
    if st.name == "state-space":
        A, B = st.system({k.split("@")[0]: v for k, v in fit.p.items() if "@" not in k or k.endswith("@0")})[:2]
        return A[:2, :2], B[:2, 0], "all six linear sway/yaw coefficients from the identified state-space model (3.1)"
    a = st.V / st.L
    K = nomoto["K'"].value * a
    if st.name == "nomoto2":
        T1, T2, T3 = (nomoto[k].value / a for k in ("T1'", "T2'", "T3'"))
        src = "K', T1', T2', T3' identified; the sway row's r and rudder terms kept from the base profile"
    else:
        T2 = nomoto_time_constants(A_b, b_b)[2]
        T1, T3 = nomoto["T'"].value / a, T2
        src = (
            f"K', T' identified (T1 = T'); the base profile's fast sway-yaw mode (T2 = {T2:.3g} s) kept and cancelled by "
            "T3 = T2, so that r/delta is exactly first order; the sway row's r and rudder terms kept from the base profile"
        )
    A, b = yaw_matched(A_b, b_b, K, T1, T2, T3)
    return A, b, src


def per_sample(A: np.ndarray, b: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, g) = (e^{A ts} - I, int_0^ts e^{A s} ds b): the exact zero-order-hold per-sample increments."""
    B = np.column_stack([b, np.zeros(2)])
    Phi, Gam, _ = discretize(A, B, np.zeros((2, 2)), np.array([ts]))
    return Phi[0] - np.eye(2), Gam[0][:, 0]


def base_document(ship: str | Path) -> tuple[dict, str]:
    """The base profile's decoded document (a built-in name or a .toml/.json file) and its name for comments."""
    import json

    path = Path(ship)
    if not path.suffix:
        path = PROFILE_DIR / f"{ship}.toml"
    text = path.read_text(encoding="utf-8")
    return (json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)), str(ship)


def check_base(base: ShipProfile) -> ShipProfile:
    """The base profile must be a 3-DOF rudder ship: its sway and yaw rows are what the model is written into."""
    if base.actuator != "rudder_propeller" or not base.planar:
        raise UserError(
            f"--save-profile: the --ship profile {base.name!r} is not a 3-DOF rudder ship (actuator {base.actuator!r}); "
            "give a rudder_propeller profile to write the identified model into"
        )
    return base


@dataclass
class SavedProfile:
    """The saved profile's TOML text, the validated profile and what the identification changed."""

    text: str
    profile: ShipProfile
    changes: list[tuple[str, float, float]]
    source_line: str


SAVED_BY = "steering --save-profile"
SAVED_HEADER = f"Ship profile written by `shiptrial {SAVED_BY}`"  # its first line: how it is known


def is_saved_profile(path: Path) -> bool:
    """A profile :func:`steering_profile` wrote: its first line is the comment opening with :data:`SAVED_HEADER`
    (``--save-profile`` replaces such a file; any other existing file only with ``--force``)."""
    from primitives.io import first_lines

    return any(line.startswith(f"# {SAVED_HEADER} ") for line in first_lines(path, 1))


def check_save_path(path: str | Path, *, force: bool = False, option: str = "path") -> Path:
    """Refuse a profile path that is not a .toml file that can be written, or an existing file that
    :func:`is_saved_profile` does not recognise, unless ``force`` (one line naming it, as ``option``: the CLI's
    "--save-profile", and the fix)."""
    from primitives.io import check_out_file

    return check_out_file(
        path, (".toml",), option, "profile", replace=force, ours=is_saved_profile, writer=f"shiptrial {SAVED_BY}"
    )


def write_saved_profile(saved: SavedProfile, path: str | Path, *, force: bool = False, option: str = "path") -> Path:
    """Write ``saved`` (:func:`steering_profile`) to ``path`` atomically; an existing file that no
    ``steering --save-profile`` wrote is refused unless ``force`` (:func:`check_save_path`)."""
    from primitives.io import atomic_write_text

    return atomic_write_text(check_save_path(path, force=force, option=option), saved.text)


def steering_profile(fit, nomoto: dict, ship: str | Path, V: float, name: str, records: list[str]) -> SavedProfile:
    """The base profile ``ship`` with its linear sway/yaw coefficients replaced by the identified model at the
    trial speed ``V`` (see the module text); checked by reading it back and re-linearising it."""
    from primitives.helm import steady_rps
    from primitives.particulars.document import toml_text
    from primitives.profile_document import profile_from_dict
    from primitives.ship import load_profile

    base = check_base(load_profile(ship))
    theta = base.params()
    n_rps = steady_rps(base, V)
    ts = base.sample_time
    lin = linearise(base, theta, V, n_rps)
    A, b, src = target_model(fit, lin, ts, nomoto)
    F, g = per_sample(A, b, ts)
    new, changes = write_linear(base, theta, lin, F, g)
    doc, base_name = base_document(ship)
    per, i = {}, 0
    for dof, terms in zip(("surge", "sway", "yaw"), base.model_terms):
        per[dof] = [float(x) for x in new[i : i + len(terms)]]
        i += len(terms)
    doc = {k: v for k, v in doc.items() if k != "prior"}
    doc.update(
        name=name,
        vessel=base.vessel or base.name,  # a model of the base's ship: diagnose takes its '# ship:' recordings as ours
        description=f"{base.name} with the steering model identified from {', '.join(records)} ({fit.structure.name}, {fit.estimator})",
        source=f"shiptrial steering (Källström 1977's output error / maximum likelihood) on {base.name}: {src}",
        parameters={"steering": per},
        simulation_set="steering",
        instrument_set="steering",
    )
    prof = profile_from_dict(doc, name)
    check = linearise(prof, prof.params(), V, n_rps)
    if not (np.allclose(check.F, F, rtol=1e-6, atol=1e-12) and np.allclose(check.g, g, rtol=1e-6, atol=1e-15)):
        raise UserError(
            f"--save-profile: profile {base.name!r}'s terms do not reproduce the identified model linearly; nothing written"
        )
    lines = [
        f"{SAVED_HEADER} from the base profile {base_name!r}.",
        f"Identified: {fit.structure.name} by {'maximum likelihood' if fit.estimator == 'ml' else 'output error'} on "
        f"{', '.join(records)} at V = {V:.3g} m/s, L = {fit.structure.L:g} m:",
        "  " + ", ".join(f"{k} {e.value:.4g} +- {1.96 * e.std:.2g}" for k, e in nomoto.items()) + " (95 %)",
        f"{src}.",
        f"From the identification (per-sample form, Ts = {ts:g} s, exact zero-order hold at V; base value -> identified):",
        *(f"  {k}: {old:.6g} -> {new_:.6g}" for k, old, new_ in changes),
        "Every other coefficient (surge, the nonlinear terms) and every other table are the base profile's; the base's",
        "[prior] spread is left out (it described the base coefficients). Linear at V only: the identified model says",
        "nothing about other speeds; the base's nonlinear terms (e.g. r*|r|) are kept and add to the identified response",
        "as the yaw rate grows (the identified K', T' already hold the trial's amplitude: compare the zig-zags).",
    ]
    header = "".join(f"# {line}\n" for line in lines)
    return SavedProfile(header + "\n" + toml_text(doc) + "\n", prof, changes, src)
