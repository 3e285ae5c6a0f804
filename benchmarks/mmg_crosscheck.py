"""Cross-check of the test-side MMG KVLCC2 (tests/physics) against the `shipmmg` package and the
MARIN free-running data: 35 deg turning circle (advance, tactical diameter) and 10/10, 20/20
zig-zags (first and second overshoot), both sides.

    python -m benchmarks.mmg_crosscheck

`shipmmg` (PyPI, MIT) is optional: without it its rows are skipped. It is never a dependency
of the product. It differs from the paper in the wake model (w_P0 exp(-4 beta_P^2) instead of
(16)) and in its example propeller position (x'_P = -0.65 instead of -0.48); the row
"ours, x'_P = -0.65" isolates the second difference.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.physics.mmg_kvlcc2 import MODEL_SCALE, RHO, kvlcc2, self_propulsion_rps
from tests.physics.mmg_sim import Manoeuvre, Run, advance, overshoots_deg, simulate_runs, straight_speed, tactical_diameter

MANS = [
    Manoeuvre("turn", 35, 0, 1, 900),
    Manoeuvre("turn", 35, 0, -1, 900),
    Manoeuvre("zigzag", 10, 10, 1, 700),
    Manoeuvre("zigzag", 10, 10, -1, 700),
    Manoeuvre("zigzag", 20, 20, 1, 700),
    Manoeuvre("zigzag", 20, 20, -1, 700),
]
MARIN = {
    "tc35-stbd": "tc_-35",
    "tc35-port": "tc_35",
    "zz10-10-stbd": "zz_-10",
    "zz10-10-port": "zz_10",
    "zz20-20-stbd": "zz_-20",
    "zz20-20-port": "zz_20",
}  # MARIN positive rudder turns to port


def figures(run: Run, man: Manoeuvre, L: float) -> dict:
    if man.kind == "turn":
        return {"AD/L": advance(run) / L, "TD/L": tactical_diameter(run) / L}
    i0 = int(np.argmax(np.abs(run.delta_mmg) > 1e-3))
    os_ = overshoots_deg(run.psi[i0:], run.delta_mmg[i0:], man.psi_deg)
    return {"OS1": os_[0] if os_ else np.nan, "OS2": os_[1] if len(os_) > 1 else np.nan}


def ours(scale: float, **coef) -> dict[str, dict]:
    ship = kvlcc2(scale)
    if coef:
        ship = replace(ship, c=replace(ship.c, **coef))
    n = self_propulsion_rps(kvlcc2(scale))
    runs = simulate_runs(ship, MANS, n, pre_s=0.0)
    return {m.label: figures(r, m, ship.L) for m, r in zip(MANS, runs)}


def marin() -> dict[str, dict]:
    from diagnose.recording import read_marin_dat

    data = Path(__file__).resolve().parents[1] / "diagnose" / "data"
    out = {}
    for m in MANS:
        rec = read_marin_dat(data / f"MARIN_FREE_KVLCC2_{MARIN[m.label]}_m.dat")
        d = rec.channels["delta"]
        i0 = int(np.argmax(np.abs(d - d[0]) > np.radians(1.0)))
        run = Run(m, rec.t[i0:], rec.pos[i0:, 0], rec.pos[i0:, 1], rec.psi[i0:], *rec.y[i0:].T, -d[i0:], rec.channels["n"][i0:])
        out[m.label] = figures(run, m, 320.0)
    return out


def shipmmg_rows() -> dict[str, dict] | None:
    try:
        from shipmmg.mmg_3dof import Mmg3DofBasicParams, Mmg3DofManeuveringParams, simulate_mmg_3dof, zigzag_test_mmg_3dof
    except ImportError:
        return None
    ship = kvlcc2(MODEL_SCALE)
    c = ship.c
    L, d = ship.L, ship.d
    q = 0.5 * RHO * L**2 * d
    bp = Mmg3DofBasicParams(
        L_pp=L,
        B=ship.B,
        d=d,
        x_G=ship.x_G,
        D_p=ship.D_p,
        m=ship.mass,
        I_zG=ship.mass * (0.25 * L) ** 2,
        A_R=ship.A_R,
        η=ship.D_p / ship.H_R,
        m_x=c.m_x * q,
        m_y=c.m_y * q,
        J_z=c.J_z * q * L**2,
        f_α=c.f_alpha,
        ϵ=c.epsilon,
        t_R=c.t_R,
        x_R=c.x_R * L,
        a_H=c.a_H,
        x_H=c.x_H * L,
        γ_R_minus=c.gamma_minus,
        γ_R_plus=c.gamma_plus,
        l_R=c.l_R,
        κ=c.kappa,
        t_P=c.t_P,
        w_P0=c.w_P0,
        x_P=-0.65,
    )
    mp = Mmg3DofManeuveringParams(
        k_0=c.k0,
        k_1=c.k1,
        k_2=c.k2,
        R_0_dash=c.R_0,
        X_vv_dash=c.X_vv,
        X_vr_dash=c.X_vr,
        X_rr_dash=c.X_rr,
        X_vvvv_dash=c.X_vvvv,
        Y_v_dash=c.Y_v,
        Y_r_dash=c.Y_r,
        Y_vvv_dash=c.Y_vvv,
        Y_vvr_dash=c.Y_vvr,
        Y_vrr_dash=c.Y_vrr,
        Y_rrr_dash=c.Y_rrr,
        N_v_dash=c.N_v,
        N_r_dash=c.N_r,
        N_vvv_dash=c.N_vvv,
        N_vvr_dash=c.N_vvr,
        N_vrr_dash=c.N_vrr,
        N_rrr_dash=c.N_rrr,
    )
    n = self_propulsion_rps(ship)
    u0 = straight_speed(ship, n)
    ts = ship.time_scale
    out = {}
    for m in MANS:
        t = np.arange(0.0, m.duration_s * ts, 0.05 * ts)
        if m.kind == "turn":
            dl = np.minimum(t * ship.rudder_rate, np.radians(35.0)) * m.side
            sol = simulate_mmg_3dof(bp, mp, t, dl, np.full(len(t), n), u0=u0, max_step=0.5 * ts)
            u, v, r, x, y, psi = sol.sol(t)[:6]
        else:
            dl, u, v, r, x, y, psi = zigzag_test_mmg_3dof(
                bp,
                mp,
                np.radians(m.delta_deg) * m.side,
                np.radians(m.psi_deg),
                t,
                np.full(len(t), n),
                δ_rad_rate=ship.rudder_rate,
                u0=u0,
            )
            dl, psi, x, y = (np.asarray(a) for a in (dl, psi, x, y))
        run = Run(m, t, np.asarray(x), np.asarray(y), np.asarray(psi), None, None, None, np.asarray(dl), None)
        out[m.label] = figures(run, m, L)
    return out


def main() -> None:
    rows = []
    t0 = time.perf_counter()
    rows.append(("ours, full scale (L = 320 m)", ours(1.0)))
    t_full = time.perf_counter() - t0
    rows.append(("ours, model scale 1:45.7 (L = 7 m)", ours(MODEL_SCALE)))
    rows.append(("ours, x'_P = -0.65 (shipmmg example)", ours(1.0, x_P=-0.65)))
    sm = shipmmg_rows()
    if sm is not None:
        rows.append(("shipmmg 0.0.11, model scale", sm))
    rows.append(("MARIN free-running (full scale)", marin()))
    print(f"KVLCC2 standard manoeuvres: AD, TD in ship lengths; OS overshoot in deg (ours: 6 runs integrated in {t_full:.1f} s)")
    print(f"{'source':40s}" + "".join(f"{m.label:>16s}" for m in MANS))
    for name, res in rows:
        cells = []
        for m in MANS:
            f = res[m.label]
            cells.append(f"{f['AD/L']:.2f}/{f['TD/L']:.2f}" if m.kind == "turn" else f"{f['OS1']:.1f}/{f['OS2']:.1f}")
        print(f"{name:40s}" + "".join(f"{c:>16s}" for c in cells))
    print("turn cells: advance/tactical diameter; zig-zag cells: first/second overshoot")
    print(f"self-propulsion rps at 7.97 m/s: {self_propulsion_rps(kvlcc2(1.0)):.3f} (full scale); MARIN approach 1.53 rps")


if __name__ == "__main__":
    main()
