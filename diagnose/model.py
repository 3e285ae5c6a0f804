"""The augmented model: baseline ``nu(k+1) = nu(k) + Phi^T theta`` plus candidate slots.

Open-loop simulation with the primitives' time step (``primitives.velocitystep.VelocityStep``, the
one every simulator uses), driven by the recorded inputs and the measured heading (which sets
the body-frame components of an earth-fixed current or wind), vectorised over a batch of
parameter vectors so that finite-difference sensitivities of all parameters cost one pass
over the time axis. Output-error fitting (Levenberg-Marquardt on the simulation residuals,
the OE method of Källström (1977)) puts the noise where it is, in the measured outputs, so the
estimates are not biased by noisy regressors (the reason Ljungberg (2022) uses IV for the
one-step predictor, section 4).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from diagnose import windload
from diagnose.candidates import Candidate, Slot
from diagnose.fitting import diverges, escaped, fit, jacobian, residuals, stack  # noqa: F401  (moved; diagnose.model's names, as before)
from diagnose.noise import noise_std, noise_std_coloured  # noqa: F401  (diagnose.model's names, as before)
from diagnose.openloop import compiled_loop, current_turning, numpy_loop
from diagnose.recording import Recording
from primitives.goodness import fit_percent  # noqa: F401  (diagnose.model.fit_percent, as before)
from primitives.ship import ShipProfile
from primitives.simulate import WIND_EXCESS, body_from_ne, relative_signals
from primitives.terms import TermSet, compile_term, signals_used

T = TypeVar("T")


@dataclass
class Prepared:
    """Arrays of one recording in the form the simulator reads."""

    rec: Recording
    y: np.ndarray  # (N+1, 3)
    psi: np.ndarray  # (N+1,)
    inputs: np.ndarray  # (N+1, m)
    y0: np.ndarray  # (3,) initial state estimate
    wind_body: tuple[np.ndarray, np.ndarray] | None  # air velocity in body axes (N+1,)
    phi: np.ndarray | None
    index: int | None = None  # position among the diagnosed recordings (its initial-state parameters)
    wind_loads: dict[str, np.ndarray] | None = None  # diagnose.windload.SIGNALS of the recorded wind (N+1,)

    @property
    def n(self) -> int:
        return len(self.y) - 1

    def cached(self, key: str, owner: object, make: Callable[[], T]) -> T:
        """``make()`` computed once from this recording (whose arrays no one changes) and
        ``owner``, the other thing it depends on (a profile, compared by identity), then kept:
        a refit simulates the same recording hundreds of times with the same inputs."""
        store = self.__dict__.setdefault("_cache", {})
        hit = store.get(key)
        if hit is None or hit[0] is not owner:
            hit = store[key] = (owner, make())
        return hit[1]


def initial_state(y: np.ndarray, m: int = 8) -> np.ndarray:
    """State at sample 0 from a straight-line fit over the first m samples (less noise, no lag)."""
    m = min(m, len(y))
    k = np.arange(m)
    coef = np.polyfit(k, y[:m], 1)
    return coef[1]


def prepare(profile: ShipProfile, rec: Recording, index: int | None = None) -> Prepared:
    wn = rec.wind_ne
    wind = None if wn is None else body_from_ne(wn, rec.psi)
    loads = None if wind is None else windload.excess_loads(profile, rec.y, wind)
    return Prepared(
        rec, rec.y, rec.psi, rec.inputs_for(profile.inputs), initial_state(rec.y), wind, rec.channels.get("phi"), index, loads
    )


class AugmentedModel:
    """Parameter vector P = [theta (baseline terms) | alpha (one entry per candidate slot)]."""

    def __init__(self, profile: ShipProfile, theta0: np.ndarray, candidates: list[Candidate], n_rec: int = 0):
        self.profile = profile
        self.theta0 = np.asarray(theta0, float)
        self.candidates = list(candidates)
        self.base = [(i, t, *compile_term(t)) for i, dof in enumerate(profile.model_terms) for t in dof]
        self.slots: list[Slot] = [s for c in self.candidates for s in c.slots]
        self.slot_of: dict[str, list[int]] = {}
        j = len(self.base)
        for c in self.candidates:
            self.slot_of[c.key] = list(range(j, j + len(c.slots)))
            j += len(c.slots)
        self.n_base = len(self.base)
        self.n_slots_end = j
        self.n_rec = n_rec  # initial-state corrections (3 per diagnosed recording), Källström 1977: the initial state estimated with the parameters
        self.n_params = j + 3 * n_rec
        # Recorded inputs sampled from a continuous actuator act, over a step, like their value
        # half a sample later than the sample (zero-order-hold convention of nu(k+1) = nu(k) + ...):
        # the delay slot is the model's shift, the physical delay is that plus half a sample.
        self.half_sample = 0.0
        # surge terms that hold the propeller thrust (n or tau_x among the factors): a "thrust" slot scales them all
        tsig = {"rudder_propeller": "n"}.get(profile.actuator, "tau_x")
        self.thrust_terms = [
            j for j, (i, t, *_r) in enumerate(self.base) if i == 0 and tsig in {f.strip("|").split("^")[0] for f in t.split("*")}
        ]
        # sway/yaw terms of the rudder (in delta or n): a thrust loss weakens them with the
        # propeller slipstream by the profile's rudder_thrust_share of the loss (MMG (24)), which a
        # resistance change does not; that is what tells the two apart at constant rpm
        self.rudder_share = float(getattr(profile, "rudder_thrust_share", 0.0))
        self.rudder_terms = [
            j
            for j, (i, t, *_r) in enumerate(self.base)
            if i > 0
            and self.rudder_share > 0
            and tsig == "n"
            and {"delta", "n"} & {f.strip("|").split("^")[0] for f in t.split("*")}
        ]
        self._slot_fn = {k: compile_term(s.term) for k, s in enumerate(self.slots, start=self.n_base) if s.kind == "term"}

    def p0(self) -> np.ndarray:
        return np.concatenate([self.theta0, np.zeros(len(self.slots) + 3 * self.n_rec)])

    def x0_params(self) -> list[int]:
        """Indices of the initial-state nuisance parameters of all diagnosed recordings."""
        return list(range(self.n_slots_end, self.n_params))

    def slot(self, j: int) -> Slot:
        return self.slots[j - self.n_base]

    # -- simulation --------------------------------------------------------------------------------
    def simulate(self, prep: Prepared, P: np.ndarray) -> np.ndarray:
        """Open-loop outputs (B, N+1, 3) for parameter vectors P (B, n_params)."""
        return self.simulate_many([prep], P)[0]

    def _plan(self, P: np.ndarray) -> dict:
        """What P switches on (the same for every recording): terms, current, steady wind, delay,
        offsets, biases, inertia scales."""
        B = P.shape[0]
        plan = {
            "terms": [],
            "cur": np.zeros((B, 2)),
            "wind": np.zeros((B, 4)),
            "delay": None,
            "offsets": [],
            "bias": np.zeros((B, 3)),
            "scale": np.ones((B, 3)),
        }
        on = np.any(P[:, : self.n_slots_end] != 0, axis=0)  # the columns any member switches on, in one pass
        for j in np.flatnonzero(on[: self.n_base]):
            i, t, names, fn = self.base[j]
            plan["terms"].append((i, P[:, j], t, names, fn))
        for j in np.flatnonzero(on[self.n_base :]) + self.n_base:
            col = P[:, j]
            s = self.slot(j)
            if s.kind == "term":
                names, fn = self._slot_fn[j]
                plan["terms"].append((s.dof, col, s.term, names, fn))
            elif s.kind == "current":
                plan["cur"][:, s.index] += col
            elif s.kind == "steady_wind":
                plan["wind"][:, s.index] += col
            elif s.kind == "delay":
                plan["delay"] = col
            elif s.kind == "offset":
                plan["offsets"].append((s.index, col))
            elif s.kind == "bias":
                plan["bias"][:, s.index] += col
            elif s.kind == "scale":
                plan["scale"][:, s.dof] += col
            elif s.kind == "thrust":  # a loss of a fraction col of the thrust: every thrust term scaled by 1 - col
                for k in self.thrust_terms:
                    i, _t, names, fn = self.base[k]
                    plan["terms"].append((i, -col * P[:, k], _t, names, fn))
                share = self.thrust_share(P, j)
                for k in self.rudder_terms:  # and the rudder terms by 1 - share * col
                    i, _t, names, fn = self.base[k]
                    plan["terms"].append((i, -share * col * P[:, k], _t, names, fn))
        return plan

    def thrust_share(self, P: np.ndarray, j: int) -> np.ndarray:
        """The rudder's share of the thrust loss of the "thrust" slot ``j``, per row of P: the
        profile's ``rudder_thrust_share`` plus the change of a following "thrust_share" slot, within
        0..1. The profile's value holds at the approach; in a turn the ship slows at the same rpm,
        the propeller loading grows and so does the share (0.55 at J = 0.28, 0.77 at J = 0.15 for
        the KVLCC2 of MMG (24)): the data say how much over the manoeuvres."""
        P = np.atleast_2d(P)
        share = np.full(P.shape[0], self.rudder_share)
        if j + 1 < self.n_slots_end and self.slot(j + 1).kind == "thrust_share":
            share = np.clip(share + P[:, j + 1], 0.0, 1.0)
        return share

    def _exogenous(self, prep: Prepared, plan: dict, B: int) -> dict[str, np.ndarray]:
        """Input-driven signals (B, N) of one recording: delayed, offset inputs and heading; (1, N),
        the same for every member, when no member delays or offsets the inputs (computed once per
        recording and profile, :meth:`Prepared.cached`, and broadcast: the same numbers)."""
        n, ts = prep.n, prep.rec.sample_time
        delay = plan["delay"]
        if delay is not None and not np.any(delay != 0):
            delay = None
        if delay is None and not plan["offsets"]:  # a new dict of the kept read-only views: a caller may add to it
            return dict(prep.cached("exogenous", self.profile, lambda: self._signals(prep, prep.inputs[:-1][None].copy())))
        x = np.broadcast_to(prep.inputs[:-1], (B, n, prep.inputs.shape[1])).copy()
        if delay is not None:
            kk = np.arange(n, dtype=float)
            base_x = prep.inputs[:-1]
            for b in range(B):
                if delay[b] != 0:
                    src = np.clip(kk - delay[b] / ts, 0, n - 1)
                    x[b] = np.stack([np.interp(src, kk, base_x[:, m]) for m in range(base_x.shape[1])], axis=-1)
        for idx, col in plan["offsets"]:
            x[:, :, idx] -= col[:, None]
        return self._signals(prep, x)

    def _signals(self, prep: Prepared, x: np.ndarray) -> dict[str, np.ndarray]:
        """The exogenous signals (B, N) of ``prep`` from its inputs ``x`` (B, N, m) as the members see them."""
        B, n = x.shape[0], prep.n
        exo = {k: np.broadcast_to(v, (B, n)) for k, v in self.profile.generalized_forces(x).items()}
        exo["psi"] = np.broadcast_to(prep.psi[:-1], (B, n))
        if prep.phi is not None:
            exo["phi"] = np.broadcast_to(prep.phi[:-1], (B, n))
        for k, v in (prep.wind_loads or {}).items():
            exo[k] = np.broadcast_to(v[:-1], (B, n))
        return exo

    def simulate_many(self, preps: list[Prepared], P: np.ndarray | list[np.ndarray]) -> list[np.ndarray]:
        """Open-loop outputs, one (B_i, N_i+1, 3) per recording, for parameter vectors P (B, n_params)
        on every recording, or one batch P[i] (B_i, n_params) per recording (a Jacobian's columns).

        One simulation with the primitives' time step (``primitives.velocitystep.VelocityStep``) over
        every batch member, recordings side by side in the compiled loop (the recordings padded to
        the longest and stepped at once in the numpy loop; :mod:`diagnose.openloop`). The
        candidate slots enter around it:
        extra terms and inertia scales in the step's terms, a current rotated by the measured
        heading, delays and offsets in the inputs, sensor biases on the outputs, initial-state
        corrections in nu(0). Input-only terms are summed before the loop and enter the step as
        its ``forced`` increments.
        """
        Ps = [np.atleast_2d(np.asarray(q, float)) for q in P] if isinstance(P, list) else None
        if Ps is not None and len(Ps) != len(preps):  # zip below would drop recordings silently
            raise ValueError(f"simulate_many: {len(Ps)} batches for {len(preps)} recordings (one batch per recording)")
        Pall = np.atleast_2d(np.asarray(P, float)) if Ps is None else np.concatenate(Ps)
        B = Pall.shape[0]
        plan = self._plan(Pall)
        scale, bias, cur = plan["scale"], plan["bias"], plan["cur"]
        loop: list[list[tuple[str, np.ndarray]]] = [[], [], []]
        for i, coef, term, names, _fn in plan["terms"]:
            if not self.input_only(names):
                loop[i].append((term, coef))
        cuts = np.cumsum([0] + [len(q) for q in Ps]) if Ps is not None else None
        rows = [slice(None)] * len(preps) if cuts is None else [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:])]
        runs = [self._run_inputs(prep, plan_rows(plan, sl), Pall[sl]) for prep, sl in zip(preps, rows)]
        tset, need = self._termset(tuple(tuple(t for t, _c in dof) for dof in loop))
        coef = np.column_stack([c * scale[:, i] for i, dof in enumerate(loop) for _t, c in dof] or [np.zeros((B, 0))])
        need_in = sorted(need & set(runs[0][0]))
        curs = [cur[sl] for sl in rows] if np.any(cur != 0) else None
        use_wind = bool(need & {*WIND_EXCESS, "u_q", "v_q"}) and any(p.wind_body is not None for p in preps)
        outs = compiled_loop(preps, runs, tset, [coef[sl] for sl in rows], need_in, curs, use_wind)
        if outs is None and Ps is None:  # the numpy loop (no compiler): the same steps
            outs = numpy_loop(preps, runs, tset, coef, need_in, None if curs is None else cur, use_wind)
        elif outs is None:  # a batch per recording: recording by recording
            outs = [
                numpy_loop([p], [run], tset, coef[sl], need_in, None if curs is None else cur[sl], use_wind)[0]
                for p, run, sl in zip(preps, runs, rows)
            ]
        if not np.any(bias):  # no sensor bias: the outputs as simulated (adding zeros copies each)
            return outs
        return [o + bias[sl][:, None, :] for o, sl in zip(outs, rows)]

    def input_only(self, names: tuple[str, ...]) -> bool:
        """Whether a term reading ``names`` reads no state: summed before the time loop."""
        return set(names) <= {"psi", "phi", *self.profile.inputs, "tau_x", "tau_y", "tau_n", *windload.SIGNALS}

    def _run_inputs(self, prep: Prepared, plan: dict, P: np.ndarray) -> tuple[dict, np.ndarray, np.ndarray]:
        """(exogenous signals, input-only increments (B, N, 3), nu(0) (B, 3)) of one recording."""
        B = P.shape[0]
        exo = self._exogenous(prep, plan, B)
        # each DOF's input-only terms summed in a contiguous (B, N) array, in the terms' order from
        # zero as they were into pre's strided column: the same sums, without the strided passes
        acc: dict[int, np.ndarray] = {}
        have = set(exo)
        for i, coef, _term, names, fn in plan["terms"]:
            if set(names) <= have:
                t = coef[:, None] * fn(exo)
                if i in acc:
                    acc[i] += t
                else:
                    acc[i] = np.zeros((B, prep.n))
                    acc[i] += t
        pre = np.zeros((B, prep.n, 3))
        for i, a in acc.items():
            pre[:, :, i] = a
        if np.any(plan["wind"][:, :2] != 0):  # a steady wind not recorded: its loads as the ship turns (diagnose.windload)
            memo = prep.cached("steady_wind", self.profile, dict)  # its still-air and recent air velocities' loads
            pre += windload.steady_increments(self.profile, prep.y, prep.psi, plan["wind"], prep.rec.sample_time, memo)[:, :-1]
        nu0 = np.broadcast_to(prep.y0, (B, 3)) - plan["bias"]
        if prep.index is not None and prep.index < self.n_rec:
            k0 = self.n_slots_end + 3 * prep.index
            nu0 = nu0 + P[:, k0 : k0 + 3]
        if np.any(plan["scale"] != 1.0):  # times 1.0 is the same number: no copy without an inertia scale
            pre = pre * plan["scale"][:, None, :]
        if np.any(plan["cur"] != 0):  # the kernel's current_turning (primitives.simulate), on the measured heading
            pre[:, :, :2] += current_turning(plan["cur"], prep.psi)
        return exo, pre, nu0

    def _termset(self, terms: tuple[tuple[str, ...], ...]) -> tuple[TermSet, set[str]]:
        """The term set of ``terms`` and the signals it reads, made once per model."""
        cache = self.__dict__.setdefault("_tsets", {})
        if terms not in cache:
            cache[terms] = (TermSet(terms), signals_used(terms))
        return cache[terms]

    # -- steps for finite differences ------------------------------------------------------------------
    def steps(self, preps: list[Prepared], P: np.ndarray) -> np.ndarray:
        """Finite-difference step per parameter, scaled to the data (all enter the model smoothly)."""
        y = np.concatenate([p.y for p in preps])
        x = np.concatenate([p.inputs for p in preps])
        dy = np.concatenate([np.diff(p.y, axis=0) for p in preps])
        ts = preps[0].rec.sample_time
        h = np.empty(self.n_params)
        for j in range(self.n_params):
            if j < self.n_base:
                h[j] = 1e-4 * max(abs(P[j]), 1e-6 * (1 + abs(P[j])))
                continue
            if j >= self.n_slots_end:
                h[j] = 0.01 * (np.std(y[:, (j - self.n_slots_end) % 3]) + 1e-9)
                continue
            s = self.slot(j)
            if s.kind == "current":
                typ = 0.01
            elif s.kind == "steady_wind" and s.index < 2:  # a secant, not a tangent: at no wind its loads are only the cross term
                typ = 0.5 * float(np.sqrt(np.mean(y[:, 0] ** 2 + y[:, 1] ** 2)))
            elif s.kind == "steady_wind":  # the centroid's arm (a fraction of the length), the surge scale
                typ = 0.01
            elif s.kind == "delay":
                typ = 0.5 * ts
            elif s.kind == "offset":
                typ = 0.01 * (np.std(x[:, s.index]) + 1e-9)
            elif s.kind == "bias":
                typ = 0.01 * (np.std(y[:, s.index]) + 1e-9)
            elif s.kind in ("scale", "thrust", "thrust_share"):
                typ = 0.01
            else:
                typ = 1e-3
                term_val = self._term_rms(preps, s)
                if term_val > 0:
                    typ = 0.01 * np.std(dy[:, s.dof]) / term_val
            h[j] = typ if s.kind == "delay" else max(typ, 1e-4 * abs(P[j]))
        return h

    def _term_rms(self, preps: list[Prepared], s: Slot) -> float:
        vals = []
        for p in preps:
            if (s.term in WIND_EXCESS or s.term in windload.SIGNALS) and p.wind_body is None:
                continue
            sig = dict(self.profile.generalized_forces(p.inputs), psi=p.psi, **(p.wind_loads or {}))
            if p.phi is not None:
                sig["phi"] = p.phi
            relative_signals(p.y, None, p.wind_body, wind_excess=True, into=sig, speed=True)
            val = compile_term(s.term)[1](sig)
            vals.append(np.asarray(val, float))
        return float(np.sqrt(np.mean(np.concatenate(vals) ** 2))) if vals else 0.0


def plan_rows(plan: dict, rows: slice) -> dict:
    """The members ``rows`` of a plan (:meth:`AugmentedModel._plan`)."""
    cut = {k: v[rows] for k, v in plan.items() if isinstance(v, np.ndarray)}
    terms = [(i, c[rows], *rest) for i, c, *rest in plan["terms"]]
    return plan | cut | {"terms": terms, "offsets": [(i, c[rows]) for i, c in plan["offsets"]]}
