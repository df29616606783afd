"""The identified friction model of one joint: one object that evaluates itself.

:class:`FrictionModel` holds any model a parameter file can name (the static maps and their per-sign
variants, LuGre, the thermal laws, and the diagnosis' extensions: position, load, drift, offset, an added
Stribeck drop) together with the joint's rigid-body terms, and evaluates it:

- :meth:`FrictionModel.friction` — the friction torque [F] at given velocities, vectorised, with the
  quantities the extensions read (joint temperature ``T``, position ``q``, carried torque ``load``,
  ``payload``, time ``t``); a LuGre model gives its steady state there;
- :meth:`FrictionModel.steady_state` — the velocity map alone, every other input at its neutral value;
- :meth:`FrictionModel.simulate` — the friction along a velocity history with the model's states (LuGre
  bristles, the joint temperature of the heat balance);
- :attr:`FrictionModel.params` — the model's numbers with unit, standard error and verdict;
  :attr:`FrictionModel.validity` — the ranges the data covered; :meth:`FrictionModel.to_dict`.

Replay (:mod:`frictid.replay`), the report and every export evaluate models through this object and the
compiled kernel it calls (:func:`frictid.models.replay_kernel.replay_friction`); nobody re-implements a
formula on a dictionary. Units: [q] rad or m, [F] N m or N, velocities [q/s].

Typical use, a feed-forward term::

    import frictid
    m = frictid.load("params.yaml", joint="j1")
    tau_ff = J * qdd_ref + m.friction(qd_ref, q=q_ref)

Numbers only: no files, no pandas. Reads a :class:`frictid.result.JointFit` by its attributes.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from .errors import ConfigError
from .models import static as sm
from .models.replay_kernel import replay_friction
from .models.thermal import canonical_at, thermal_code

#: Parameter names of the diagnosis extensions (see docs/parameter-file.md, "Extended models").
EXTENSION_PARAMS = {
    "position": ("pos_amp", "pos_period", "pos_phase", "pos_q0", "pos_lin", "pos_quad"),
    "load": ("load_torque", "load_gravity", "load_payload"),
    "offset": ("tau_offset",),
    "drift": ("drift_per_hour", "drift_t0"),
    "stribeck": ("str_amp", "str_vs", "str_delta", "str_amp_neg"),
    "presliding": ("sigma0", "sigma1"),
    "inertia": ("J",),
    "gravity": ("Px", "Py"),
    "ripple": ("rip_period", "rip_sin", "rip_cos"),
    "temperature": ("alpha", "beta", "lam", "dc0", "dc1", "dc2", "dc3", "C", "K", "T0"),
}

#: Each static map in words and in symbols (F [F] at velocity w [q/s]).
MAP_FORMULAS = {
    "coulomb_viscous": ("Coulomb level plus viscous friction", "F = Fc sgn(w) + sigma2 w"),
    "stribeck": ("Coulomb level with a Stribeck drop from the break-away level at low speed, plus viscous "
                 "friction", "F = (Fc + (Fs - Fc) exp(-|w/vs|^delta)) sgn(w) + sigma2 w"),
    "stribeck_2exp": ("level with two exponential terms (a Stribeck drop, then a second exponential), plus viscous and "
                      "quadratic friction", "F = (alpha0 + alpha1 exp(-|w|/ws1) + alpha2 (1 - exp(-|w|/ws2))) "
                      "sgn(w) + alpha3 w + alpha4 w|w|"),
    "polynomial": ("third-order polynomial in velocity", "F = c0 sgn(w) + c1 w + c2 w|w| + c3 w^3"),
}
#: What each model term adds to the map, in symbols (g: the map's level, F: the friction).
TERM_FORMULAS = {
    "asym": "parameters _pos for w >= 0, _neg for w < 0",
    "lugre": "LuGre: dz/dt = w - sigma0 |w| z / g(w), F = sigma0 z + sigma1 dz/dt + viscous part; steady "
             "state: the map",
    "thermal4": "at joint temperature T every amplitude is scaled by alpha (T - T0) + beta",
    "thermal6": "at joint temperature T each coefficient is c_i + dc_i (T - T0)",
    "exponential": "at joint temperature T every amplitude is scaled by exp(-lam (T - T0))",
    "position": "g scaled by 1 + pos_amp sin(2 pi q / pos_period + pos_phase) (periodic) or "
                "1 + pos_lin (q - pos_q0) + pos_quad (q - pos_q0)^2",
    "load": "g scaled by 1 + load_torque |J a + G(q)| + load_gravity |G(q)| + load_payload m",
    "drift": "F scaled by 1 + drift_per_hour (t - drift_t0) / 3600",
    "offset": "F + tau_offset",
    "stribeck": "g + str_amp exp(-(|w|/str_vs)^str_delta)",
    "low_speed_rise": "g + str_amp exp(-(|w|/str_vs)^str_delta), str_amp < 0: below the level at low speed",
    "low_speed": "g + str_amp exp(-(|w|/str_vs)^str_delta), str_amp (w >= 0) and str_amp_neg (w < 0) of "
                 "opposite signs",
}

#: Each term in words.
TERM_WORDS = {"asym": "its own parameters per velocity sign", "lugre": "LuGre bristle dynamics",
              "thermal4": "scaled with joint temperature (thermal4)",
              "thermal6": "coefficients linear in joint temperature (thermal6)",
              "exponential": "scaled exponentially with joint temperature", "position": "varies with position",
              "load": "grows with the transmitted load", "drift": "drifts with time",
              "offset": "with a constant torque offset", "stribeck": "with an added Stribeck drop",
              "low_speed_rise": "with a low-speed rise (friction below the sliding level at low speed, rising "
                                "to it)",
              "low_speed": "with a low-speed term (a drop on one velocity sign, a rise on the other)"}

#: Relative margin beyond a validity range before an evaluation warns.
VALIDITY_MARGIN = 0.05


class ValidityWarning(UserWarning):
    """An evaluation outside the ranges the model was identified on (or without an input it needs)."""


# ---------------------------------------------------------------------------------------------------
# Rigid-body torque and the extension multipliers (shared with frictid.diagnose)


def rigid_torque(q, axis: str, Px: float, Py: float, offset: float, payload=None, Mx: float = 0.0,
                 My: float = 0.0) -> np.ndarray:
    """Gravity, payload and offset torque [F] at positions q [q]: ``Px cos q + Py sin q + offset`` on a
    rotary axis (``offset`` on a linear one), plus ``payload`` [kg] per sample times ``Mx cos q + My sin q``
    (times ``Mx`` on a linear axis)."""
    q = np.asarray(q, dtype=float)
    if axis == "rotary" and (Px or Py):
        # Px cos q + Py sin q = R cos(q - phi): one trigonometric function per sample instead of two
        G = np.subtract(q, math.atan2(Py, Px))
        np.cos(G, out=G)
        G *= math.hypot(Px, Py)
        G += offset
    else:
        G = np.full(q.shape[0], offset, dtype=float)
    if payload is not None:
        pay = np.asarray(payload, dtype=float)
        G = G + (Mx * pay * (np.cos(q) if axis == "rotary" else 1.0))
        if axis == "rotary":
            G = G + My * pay * np.sin(q)
    return G


def position_factor(q, ext: dict) -> np.ndarray:
    """Level multiplier [1] of the position extension at positions q [q].

    Periodic: ``1 + pos_amp sin(2 pi q / pos_period + pos_phase)``; smooth (non-periodic):
    ``1 + pos_lin (q - pos_q0) + pos_quad (q - pos_q0)^2``. Absent parameters count as zero.
    """
    q = np.asarray(q, dtype=float)
    out = np.ones_like(q)
    amp = ext.get("pos_amp")
    if amp:
        out = out + amp * np.sin(2 * np.pi * q / ext["pos_period"] + ext.get("pos_phase", 0.0))
    lin, quad = ext.get("pos_lin") or 0.0, ext.get("pos_quad") or 0.0
    if lin or quad:
        d = q - (ext.get("pos_q0") or 0.0)
        out = out * (1.0 + lin * d + quad * d * d)
    return out


def load_factor(load_abs, G_abs, payload, ext: dict) -> np.ndarray | float:
    """Level multiplier [1] of the load extension:
    ``1 + load_torque |J a + G| + load_gravity |G| + load_payload m``.

    load_abs : the torque the transmission carries besides friction, ``|J a + G(q)|`` [F] (inertial and
    gravity torque; not the measured torque, which contains the friction itself); G_abs : |gravity
    torque| [F]; payload [kg] (arrays or None).
    """
    out = 1.0
    for key, x in (("load_torque", load_abs), ("load_gravity", G_abs), ("load_payload", payload)):
        k = ext.get(key)
        if k and x is not None:
            out = out + k * np.asarray(x, dtype=float)
    return out


def drift_factor(t_abs, ext: dict) -> np.ndarray | float:
    """Whole-map multiplier [1] of the drift extension: ``1 + drift_per_hour (t_abs - drift_t0) / 3600``."""
    k = ext.get("drift_per_hour")
    if not k or t_abs is None:
        return 1.0
    return 1.0 + k * (np.asarray(t_abs, dtype=float) - (ext.get("drift_t0") or 0.0)) / 3600.0


# ---------------------------------------------------------------------------------------------------
# The model object


@dataclass
class FrictionModel:
    """One identified model of one joint. Units: [q] rad or m, [F] N m or N.

    name, map : model name and its static map. c_pos, c_neg : canonical vectors (w >= 0, w < 0) of
    :mod:`frictid.models.static`. sigma0, sigma1 : LuGre stiffness and damping per bristle sign (None:
    a static model). J [kg m^2 | kg], Px, Py [F], Mx, My [F/kg], offset [F]: rigid-body terms (offset:
    the joint's torque offset; a diagnosis model carries its own as ``ext["tau_offset"]``, which
    :meth:`friction` includes). thermal : law ('thermal4', 'thermal6', 'exponential') and its numbers, or
    None. ext : extension parameters by name. params : the model's numbers (name -> ParamEstimate).
    validity : ranges the data covered (``speed``: [lo, hi] of |w|, ``temperature``, ``position``), or {}.
    """

    name: str
    map: str
    c_pos: np.ndarray
    c_neg: np.ndarray
    axis: str = "rotary"
    sigma0: tuple[float, float] | None = None
    sigma1: tuple[float, float] = (0.0, 0.0)
    J: float = 0.0
    Px: float = 0.0
    Py: float = 0.0
    Mx: float = 0.0
    My: float = 0.0
    offset: float = 0.0
    thermal: dict | None = None
    ext: dict = field(default_factory=dict)
    joint: str = ""
    params: dict = field(default_factory=dict)
    validity: dict = field(default_factory=dict)

    @classmethod
    def from_joint(cls, jf, name: str | None = None) -> "FrictionModel":
        """Model ``name`` (default: the selected one) of a joint's fit (:class:`frictid.result.JointFit`).
        Raises :class:`~frictid.errors.ConfigError` when the model is missing or incomplete."""
        name = name or jf.selected
        if not name:
            raise ConfigError(f"joint {jf.joint}: the parameter file has no selected model; name one with --model")
        if name not in jf.models:
            raise ConfigError(f"joint {jf.joint}: no model {name!r} in the parameter file; models: "
                              + ", ".join(jf.models))
        mf = jf.models[name]
        try:
            sm.split_asym(mf.map)
        except KeyError as exc:
            raise ConfigError(f"joint {jf.joint}, model {name}: {exc.args[0]}") from None
        ext = _extension_values(mf.params)
        c_pos, c_neg = sm.canonical_pair(mf.map, _static_params(mf.map, mf.params))
        if ext.get("str_amp") or ext.get("str_amp_neg"):  # the stribeck extension: the canonical Stribeck slot
            # of a map that has none; str_amp_neg: the w < 0 branch's own amplitude (a per-sign model's)
            amps = (ext.get("str_amp", 0.0), ext.get("str_amp_neg", ext.get("str_amp", 0.0)))
            for c, amp in zip((c_pos, c_neg), amps):
                c[1], c[2], c[3] = amp, ext["str_vs"], ext.get("str_delta", 2.0)
        m = cls(name=name, map=mf.map, c_pos=c_pos, c_neg=c_neg, axis=jf.axis, ext=ext, joint=str(jf.joint),
                params=dict(mf.params), validity=dict(getattr(jf, "validity", None) or {}),
                **_rigid_terms(jf, mf, ext))
        m.sigma0, m.sigma1 = _lugre_pairs(mf.params, ext)
        m.thermal = _thermal_law(jf, mf, ext)
        return m

    # ---- rigid body

    def gravity(self, q, payload=None):
        """Gravity and offset torque G(q) [F] (payload [kg] per sample or None), with the torque ripple that
        follows the position where the model has one (:meth:`ripple`)."""
        if q is None:
            return np.asarray(self.offset, dtype=float)
        G = rigid_torque(q, self.axis, self.Px, self.Py, self.offset, payload, self.Mx, self.My)
        return G + self.ripple(q) if self.ext.get("rip_period") else G

    def ripple(self, q):
        """The torque ripple that follows the position [F]: ``rip_sin sin(2 pi q / rip_period) + rip_cos
        cos(2 pi q / rip_period)`` (a motor's cogging, a gear's tooth period; 0 without one)."""
        ext = self.ext
        if not ext.get("rip_period"):
            return np.zeros(np.shape(q))
        x = (2.0 * math.pi / ext["rip_period"]) * np.asarray(q, dtype=float)
        return ext.get("rip_sin", 0.0) * np.sin(x) + ext.get("rip_cos", 0.0) * np.cos(x)

    # ---- evaluation

    def multipliers(self, t_abs, q, a, payload, G=None, load=None) -> tuple[np.ndarray, np.ndarray]:
        """Level and viscous multipliers (gmul, fmul) [1] per sample of the model's extensions (each of
        length 1 when it is the same for every sample).

        t_abs [s] time on the drift clock; q [q] or None; a [q/s^2] acceleration; payload [kg] or None;
        G [F] the gravity torque without the offset (default from the model); load [F]: the carried torque
        ``|J a + G|`` when the caller has it (then ``a`` is not read).
        """
        ext = self.ext
        gmul = np.ones(1)  # length 1: the same for every sample (the replay kernel takes it so)
        if q is not None and (ext.get("pos_amp") or ext.get("pos_lin") or ext.get("pos_quad")):
            gmul = gmul * position_factor(q, ext)
        if ext.get("load_torque") or ext.get("load_gravity") or ext.get("load_payload"):
            if G is None:
                G = self.gravity(q, payload) - self.offset if q is not None else np.zeros(1)
            if load is None:
                load = np.abs(self.J * np.nan_to_num(np.asarray(a, dtype=float)) + G)
            gmul = gmul * load_factor(np.abs(load), np.abs(G), payload, ext)
        d = drift_factor(t_abs, ext)
        fmul = np.ones(1)
        if np.ndim(d) or d != 1.0:
            fmul = fmul * d
            gmul = gmul * d
        return gmul, fmul

    def friction(self, w, *, T=None, q=None, load=None, payload=None, t=None) -> np.ndarray:
        """Friction torque [F] at joint velocities w [q/s] (any shape), in steady state.

        T : joint temperature [degC] (thermal models; default their reference temperature T0);
        q : position [q] (position extension; gravity is not friction and is not included);
        load : torque the transmission carries besides friction, ``|J a + G|`` [F] (load extension);
        payload [kg]; t : time on the drift clock [s] (drift extension). Each broadcasts against w. An
        input an extension needs but is not given leaves that extension at its neutral value, with a
        :class:`ValidityWarning`; so does a velocity, temperature or position outside :attr:`validity`.
        """
        w = np.asarray(w, dtype=float)
        shape = w.shape
        flat = w.reshape(-1)
        bc = (lambda x: None if x is None else np.broadcast_to(np.asarray(x, dtype=float), shape).reshape(-1))
        T, q, load, payload, t = (bc(x) for x in (T, q, load, payload, t))
        self._check_inputs(flat, T, q, load, payload, t)
        gmul, fmul = self.multipliers(t, q, None, payload, load=load if load is not None else 0.0)
        F = self._static(flat, gmul, fmul, T) + self.ext.get("tau_offset", 0.0)
        return F.reshape(shape)

    def steady_state(self, w) -> np.ndarray:
        """The velocity map F_ss(w) [F]: the model at its reference temperature with no position, load or
        drift effect and without a torque offset (:meth:`friction` with every other input neutral)."""
        w = np.asarray(w, dtype=float)
        return self._static(w.reshape(-1), np.ones(1), np.ones(1), None).reshape(w.shape)

    def _at(self, T):
        """The joint temperature a steady-state evaluation uses: T, or the thermal law's reference T0."""
        return self.thermal["T0"] if T is None and self.thermal else T

    def _static(self, w, gmul, fmul, T) -> np.ndarray:
        F, _, _ = replay_friction(np.arange(w.shape[0], dtype=float), w, self.c_pos, self.c_neg,
                                  gmul=gmul, fmul=fmul, thermal=self.thermal_input(w.shape[0], T=self._at(T)))
        return F

    def simulate(self, t, w, *, z0: float = 0.0, T=None, Tenv=None, T_init=None, q=None, load=None,
                 payload=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Friction along a velocity history, with the model's states. Returns ``(F, z, T)``.

        t [s] increasing sample times, w [q/s] velocities at those times; z0 [q] initial bristle
        deflection (LuGre); T [degC] a measured joint temperature per sample, or else Tenv [degC] (scalar
        or per sample; default T0) and T_init [degC] for the heat balance of a thermal model; q, load,
        payload as in :meth:`friction`, per sample. F [F], z [q] bristle deflection (zeros for a static
        model, whose sign law holds down to w = 0), T [degC] joint temperature (NaN without a thermal law).
        """
        t = np.asarray(t, dtype=float)
        w = np.asarray(w, dtype=float)
        n = w.shape[0]
        gmul, fmul = self.multipliers(t if self.ext.get("drift_per_hour") else None, q, None, payload,
                                      load=load if load is not None else 0.0)
        th = self.thermal_input(n, T=T, Tenv=Tenv, T_init=T_init)
        F, z, T_out = replay_friction(t, w, self.c_pos, self.c_neg, gmul=gmul, fmul=fmul, sigma0=self.sigma0,
                                      sigma1=self.sigma1, z0=z0, thermal=th)
        return F + self.ext.get("tau_offset", 0.0), z, T_out

    def canonical_at(self, T: float) -> tuple[np.ndarray, np.ndarray]:
        """The canonical vectors (w >= 0, w < 0) at joint temperature T [degC]: the thermal law applied to the
        amplitudes (the identified vectors themselves for a model without one)."""
        law = self.thermal_law()
        if law is None:
            return self.c_pos.copy(), self.c_neg.copy()
        return (canonical_at(self.c_pos, T, law["code"], law["theta"], law["dc_pos"]),
                canonical_at(self.c_neg, T, law["code"], law["theta"], law["dc_neg"]))

    # ---- the thermal law as the kernel takes it

    def thermal_law(self) -> dict | None:
        """``code``, ``theta``, ``dc_pos``, ``dc_neg`` of the thermal law for the replay kernel, or None."""
        th = self.thermal
        if not th:
            return None
        code, theta, dc9 = thermal_code(th["law"], th["alpha"], th["beta"], th["lam"], th["T0"], th["dc"])
        return {"code": code, "theta": theta, "dc_pos": dc9, "dc_neg": dc9}

    def thermal_input(self, n: int, T=None, Tenv=None, T_init=None) -> dict | None:
        """The thermal law as the replay kernel takes it over n samples, or None without one: at the joint
        temperature T [degC] (scalar or per sample) when given; else along the heat balance from the
        ambient Tenv [degC] (scalar or per sample; default T0), starting at T_init (default the first
        ambient value, or T0 for no samples)."""
        law = self.thermal_law()
        if law is None:
            return None
        th = self.thermal
        if T is not None:
            law["T"] = np.broadcast_to(np.asarray(T, dtype=float), (n,))
            return law
        if th.get("C") is None or th.get("K") is None:
            raise ConfigError(f"joint {self.joint}, model {self.name}: the thermal law reads a measured joint "
                              "temperature; pass T")
        Tenv = np.full(n, th["T0"]) if Tenv is None else np.broadcast_to(np.asarray(Tenv, dtype=float), (n,))
        if T_init is None:
            T_init = Tenv[0] if n else th["T0"]
        law.update(C=th["C"], K=th["K"], Tenv=Tenv, T_init=float(T_init))
        return law

    # ---- honesty about the inputs

    def _check_inputs(self, w, T, q, load, payload, t) -> None:
        ext = self.ext
        needs = {"q": bool(ext.get("pos_amp") or ext.get("pos_lin") or ext.get("pos_quad")),
                 "load": bool(ext.get("load_torque") or ext.get("load_gravity")),
                 "payload": bool(ext.get("load_payload")), "t": bool(ext.get("drift_per_hour"))}
        given = {"q": q, "load": load, "payload": payload, "t": t}
        missing = [k for k, need in needs.items() if need and given[k] is None]
        if missing:
            warnings.warn(f"joint {self.joint}, model {self.name}: without {', '.join(missing)} its "
                          f"{'/'.join(missing)} extension is left at its neutral value", ValidityWarning,
                          stacklevel=3)
        # the ranges of what the model depends on: any speed down to rest is in a map's range; position and
        # temperature only where the model has a term for them
        self._check_range("speed", np.abs(w), below=False)
        if self.thermal:
            self._check_range("temperature", T)
        if needs["q"]:
            self._check_range("position", q)

    def _check_range(self, key: str, x, below: bool = True) -> None:
        rng = self.validity.get(key)
        if rng is None or x is None or rng[0] is None or rng[1] is None:
            return
        x = np.asarray(x, dtype=float)
        x = x[np.isfinite(x)]
        lo, hi = float(rng[0]), float(rng[1])
        pad = VALIDITY_MARGIN * max(hi - lo, abs(hi), 1e-12)
        if x.size and ((below and x.min() < lo - pad) or x.max() > hi + pad):
            warnings.warn(f"joint {self.joint}, model {self.name}: {key} {x.min():.4g}..{x.max():.4g} is outside "
                          f"the range the model was identified on ({lo:.4g}..{hi:.4g}); the values there are "
                          "extrapolated", ValidityWarning, stacklevel=4)

    # ---- plain data

    def terms(self) -> list[str]:
        """The model's terms beyond its static map, by name (keys of :data:`TERM_FORMULAS`)."""
        ext = self.ext
        out = ["asym"] if self.map.endswith("_asym") else []
        out += ["lugre"] if self.sigma0 is not None else []
        out += [self.thermal["law"]] if self.thermal else []
        checks = {"position": ("pos_amp", "pos_lin", "pos_quad"), "load": ("load_torque", "load_gravity",
                  "load_payload"), "drift": ("drift_per_hour",), "offset": ("tau_offset",),
                  "stribeck": ("str_amp", "str_amp_neg")}
        # the low-speed term is named by its amplitudes' signs (sm.low_speed_name: a rise is no Stribeck drop)
        low = sm.low_speed_name([ext[k] for k in checks["stribeck"] if k in ext])
        return out + [low if t == "stribeck" else t for t, keys in checks.items() if any(ext.get(k) for k in keys)]

    def formula(self) -> dict:
        """The model in words and symbols: ``words``, ``friction`` (the map and each term), ``torque`` (the
        one-line joint torque with the rigid-body terms and the offset convention it is used with)."""
        words, sym = MAP_FORMULAS[sm.split_asym(self.map)[0].name]
        terms = self.terms()
        grav = ("Px cos(q) + Py sin(q)" + (" + payload (Mx cos(q) + My sin(q))" if self.Mx or self.My else "")
                if self.axis == "rotary" else "0")
        off = "tau_offset (in F)" if "offset" in terms else "offset"
        rip = (" + rip_sin sin(2 pi q / rip_period) + rip_cos cos(2 pi q / rip_period)"
               if self.ext.get("rip_period") else "")
        return {"words": "; ".join([words] + [TERM_WORDS[t] for t in terms]),
                "friction": [sym] + [TERM_FORMULAS[t] for t in terms],
                "torque": f"tau = J a + {grav}{rip} + {off} + F(w)"}

    def head(self) -> dict:
        """What a feed-forward user needs of this model, for the top of a joint in the parameter file: name,
        formula, parameters (value, unit, stderr, identifiable), rigid-body terms and validity."""
        whole = self.to_dict()
        params = {}
        for n, d in whole["params"].items():
            params[n] = {k: d.get(k) for k in ("value", "unit", "stderr", "identifiable")}
            if d.get("fixed"):  # held at a value (delta at 2, a drop the data cannot see): said so, with why
                params[n]["fixed"] = True
            if d.get("reason") and (d.get("fixed") or not d.get("identifiable", True)):
                params[n]["reason"] = d["reason"]
        return {"name": self.name, **self.formula(), "params": params, "rigid_body": whole["rigid_body"],
                "validity": whole["validity"]}

    def to_dict(self) -> dict:
        """The model as plain data: name, map, axis, parameters (value, unit, stderr, verdict), the rigid-body
        terms it is used with, and its validity ranges."""
        params = {n: (p.to_dict() if hasattr(p, "to_dict") else dict(p)) for n, p in self.params.items()}
        rigid = {"J": self.J, "Px": self.Px, "Py": self.Py, "offset": self.offset}
        if self.Mx or self.My:
            rigid.update(Mx=self.Mx, My=self.My)
        return {"joint": self.joint, "name": self.name, "map": self.map, "axis": self.axis, "params": params,
                "rigid_body": rigid, "validity": dict(self.validity)}


# ---------------------------------------------------------------------------------------------------
# Reading a joint's fit


def _value(params: dict, name: str):
    p = params.get(name)
    if p is None:
        return None
    v = p.value if hasattr(p, "value") else (p.get("value") if isinstance(p, dict) else p)
    return None if v is None else float(v)


def _static_params(mapname: str, params: dict) -> dict:
    names = [p.name for p in sm.param_table(mapname)]
    vals = {n: _value(params, n) for n in names}
    missing = [n for n, v in vals.items() if v is None]
    if missing:
        raise ConfigError(f"model parameters {', '.join(missing)} of map {mapname} have no value")
    return vals


def _extension_values(params: dict) -> dict:
    ext = {}
    for names in EXTENSION_PARAMS.values():
        for n in names:
            v = _value(params, n)
            if v is not None:
                ext[n] = v
    return ext


def _rigid_terms(jf, mf, ext: dict) -> dict:
    """J, Px, Py, Mx, My, offset of model ``mf``: the joint's, with the diagnosis' corrections."""
    def rb(pe, default=0.0):
        return float(pe.value) if pe is not None and pe.value is not None else default

    out = {"J": rb(jf.inertia), "offset": rb(jf.offset)}
    out.update({k: rb(jf.gravity.get(k)) for k in ("Px", "Py", "Mx", "My")})
    out.update({k: ext[k] for k in ("J", "Px", "Py") if k in ext})
    if (mf.extra or {}).get("extensions") is not None and (jf.offset is None or
                                                           jf.offset.source != "log metadata"):
        # a diagnosis model: the torque offset is one of its terms (tau_offset), not the fit's estimate
        out["offset"] = 0.0
    return out


def _lugre_pairs(params: dict, ext: dict):
    if "sigma0" not in ext:
        return None, (0.0, 0.0)
    s0n = _value(params, "sigma0_neg")
    s1n = _value(params, "sigma1_neg")
    s1 = ext.get("sigma1", 0.0)
    return (ext["sigma0"], s0n if s0n is not None else ext["sigma0"]), (s1, s1n if s1n is not None else s1)


def _thermal_law(jf, mf, ext: dict) -> dict | None:
    law = ("thermal6" if "dc0" in ext else "thermal4" if "alpha" in ext else
           "exponential" if "lam" in ext else None)
    if not law:
        return None
    missing = [k for k in ("C", "K") if k not in ext]
    source = (mf.extra or {}).get("temperature", "heat_balance")
    if missing and source != "temp_joint":
        raise ConfigError(f"joint {jf.joint}, model {mf.name}: thermal law {law} without {', '.join(missing)}")
    return {"law": law, "alpha": ext.get("alpha", 0.0), "beta": ext.get("beta", 1.0),
            "lam": ext.get("lam", 0.0), "T0": ext.get("T0", 25.0),
            "dc": [ext.get(f"dc{i}", 0.0) for i in range(4)],
            "C": ext.get("C"), "K": ext.get("K"), "source": source}
