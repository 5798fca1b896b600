"""The hydrodynamic passive callback compiled to native code (numba `cfunc`).

Same physics as the Python reference `callbacks.passive_force` +
`physics.hydrodynamics.hydrodynamic_force`, but installed in MuJoCo as a C
function pointer, so the bindings call it without taking the GIL: stepping is
as fast as MuJoCo's own pipeline allows and `mujoco.rollout` can run many
twins on several threads.

One compiled function serves every vessel and parameter set because it reads
the vessel parameters FROM THE MODEL: `with_native_params` stores them as the
model's first custom numeric `twin_params` (layout `LAYOUT`). A model whose
first numeric does not start with the two magic numbers is left alone, so the
callback can stay installed while other models are simulated.

A propeller-and-rudder ship's MMG forces and a Fujiwara wind load are the very functions of
physics/mmg.py and physics/fujiwara.py compiled by numba; they read the ship's inputs (n, δ)
from the controls 0 and 1, and a model with wind inputs the air's velocity from its controls 2
and 3 (mjcf.add_wind_inputs). The layout grew at its end for them; a twin-thruster vessel's
parameters leave them off and its forces are computed as before, operation for operation.

The callback reads mjModel/mjData fields through byte offsets into the C
structs. They are found once, at import, from the shipped headers (field order)
and the live structs (one anchor address found by scanning), and every
offset is verified against the addresses and values the bindings expose.
"""
from __future__ import annotations

import contextlib
import ctypes
import hashlib
import re
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np
from llvmlite import binding as llvm
from llvmlite import ir
from numba import carray, cfunc, njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from ..errors import TwinError
from ..physics import environment, fujiwara, hydrostatics, mmg, seakeeping, waves
from ..physics.environment import RHO_AIR_KG_M3
from ..physics.hydrodynamics import HydroModel, Terms
from . import callbacks
from .mjcf import THRUSTERS, CompiledVessel, edited_spec, make_lean, wind_control

PARAMS_NAME = "twin_params"
MAGIC = (7.0710678118654752e11, -2.7182818284590452e-13)  # unlikely to be anyone else's first numeric

_FIELDS = (  # (name, number of doubles), in storage order
    ("magic", 2), ("size", 1), ("qpos_adr", 3), ("dof_adr", 3),
    ("switches", 6),  # added_mass, added_mass_coriolis, damping, thrust, current, wind (0/1, effective)
    ("M_RB", 9), ("M_A", 9), ("M_inv", 9),  # row-major, kg / kg m / kg m²
    ("damping", 19),  # Damping.names() order, Fossen's signs (the last, astern_excess, dimensionless)
    ("wind_load", 6),  # A_F m², A_L m², L m, c_x, c_y, c_n
    ("current_ned", 2), ("wind_ned", 2),  # m/s; wind as the air's velocity
    ("flags", 4),  # Munk moment in C_A (0/1), MMG forces (0/1), first wind control (−1: none), Fujiwara (0/1)
    ("mmg_switches", 3),  # MMG hull, propeller, rudder (0/1)
    ("mmg", mmg.SIZE),  # physics.mmg.FIELDS
    ("fujiwara", fujiwara.SIZE),  # physics.fujiwara.pack
    ("advance", 5),  # advance loss c (√N·s/m, 0: none), thruster y_L, y_R (m), their actuator ids
    ("sea_load", seakeeping.KNOWN_SIZE),  # a known sea's mean load (physics.seakeeping.pack_known_load; 0: none)
)


def _layout() -> dict[str, slice]:
    out, start = {}, 0
    for name, n in _FIELDS:
        out[name] = slice(start, start + n)
        start += n
    return out


LAYOUT = _layout()
NPARAM = max(s.stop for s in LAYOUT.values())


# ---------------------------------------------------------------- parameters

def pack_params(hydro: HydroModel, model: mujoco.MjModel) -> np.ndarray:
    """The float64 vector the native callback reads (see `LAYOUT`).

    The current and wind switches are stored *effective* (term on AND speed
    non-zero), exactly the conditions under which the Python reference applies
    them. M_inv is the inverse of M_RB + M_A (M_RB alone without added mass).
    """
    qpos, dof = callbacks._joint_indices(model)
    t, env = hydro.terms, hydro.environment
    wind_ctrl = wind_control(model)
    switches = (t.added_mass, t.added_mass_coriolis, t.damping, t.thrust,
                t.current and env.has_flow,
                t.wind and (env.wind_speed_m_s != 0.0 or wind_ctrl >= 0))
    w = hydro.wind_load
    values = {
        "magic": MAGIC, "size": (NPARAM,), "qpos_adr": qpos, "dof_adr": dof,
        "switches": [float(s) for s in switches],
        "M_RB": np.ravel(hydro.M_RB), "M_A": np.ravel(hydro.M_A), "M_inv": np.ravel(hydro.M_inv),
        "damping": [getattr(hydro.damping, n) for n in type(hydro.damping).names()],
        "wind_load": (w.frontal_area_m2, w.lateral_area_m2, w.length_m, w.cx, w.cy, w.cn),
        "current_ned": env.flow_ned, "wind_ned": env.wind_ned,
        "flags": (float(hydro.munk_moment), float(hydro.mmg is not None), float(wind_ctrl),
                  float(hydro.wind_regression is not None)),
        "mmg_switches": (float(t.mmg_hull), float(t.propeller), float(t.rudder)),
        "mmg": np.zeros(mmg.SIZE) if hydro.mmg is None else hydro.mmg,
        "fujiwara": np.zeros(fujiwara.SIZE) if hydro.wind_regression is None else hydro.wind_regression,
        "advance": _advance(hydro, model),
        "sea_load": np.asarray(env.wave_load, float) if env.wave_load else np.zeros(seakeeping.KNOWN_SIZE),
    }
    p = np.zeros(NPARAM)
    for name, sl in LAYOUT.items():
        p[sl] = values[name]
    return p


def _advance(hydro: HydroModel, model: mujoco.MjModel) -> tuple[float, ...]:
    """The advance loss's numbers (LAYOUT): c, where the thrusters sit and which actuators they are."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in THRUSTERS]
    if not hydro.advance_loss or min(ids) < 0:
        return (0.0, 0.0, 0.0, 0.0, 0.0)
    return (float(hydro.advance_loss), *map(float, hydro.thruster_y_m), float(ids[0]), float(ids[1]))


def _params_view(model: mujoco.MjModel) -> np.ndarray:
    """The model's `twin_params` slice of numeric_data (a writable view)."""
    if (model.nnumeric < 1 or mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_NUMERIC, 0) != PARAMS_NAME
            or model.numeric_size[0] != NPARAM):
        raise TwinError(f"model has no '{PARAMS_NAME}' numeric of size {NPARAM} first: "
                        "build it with with_native_params")
    adr = int(model.numeric_adr[0])
    return model.numeric_data[adr:adr + NPARAM]


def set_params(model: mujoco.MjModel, hydro: HydroModel) -> None:
    """Overwrite the model's parameters in place: a parameter change needs no recompilation."""
    _params_view(model)[:] = pack_params(hydro, model)


def has_params(model: mujoco.MjModel) -> bool:
    """True when the native callback will act on this model."""
    try:
        p = _params_view(model)
    except TwinError:
        return False
    return bool(p[0] == MAGIC[0] and p[1] == MAGIC[1])


def with_native_params(compiled: CompiledVessel, terms: Terms | None = None,
                       wind_inputs: bool | None = None, lean: bool = False) -> mujoco.MjModel:
    """The vessel's model recompiled with `twin_params` as its first custom numeric.

    Built from the vessel's spec with the same edits as `compile_vessel`, so the
    dynamics are identical to `compiled.model`; parameters from `compiled.hydro(terms)`.
    wind_inputs: the wind as controls 2 and 3 (default: as `compiled` has them). lean: without
    the parts only a viewer needs (`mjcf.make_lean`: same dynamics up to round-off, faster).
    """
    wind_inputs = compiled.wind_inputs if wind_inputs is None else wind_inputs
    spec = edited_spec(compiled.vessel, wind_inputs)
    if lean:
        make_lean(spec, compiled.geometry.rigid)
    others = [(n.name, list(n.data), n.size) for n in spec.numerics]
    for n in list(spec.numerics):
        spec.delete(n)
    spec.add_numeric(name=PARAMS_NAME, data=np.zeros(NPARAM), size=NPARAM)
    for name, data, size in others:
        spec.add_numeric(name=name, data=data, size=size)
    model = spec.compile()
    set_params(model, compiled.hydro(terms))
    return model


# ---------------------------------------------------------------- struct offsets

_INCLUDE = Path(mujoco.__file__).resolve().parent / "include" / "mujoco"
_SIZE_DECL = re.compile(r"^\s*mjtSize\s+(\w+)\s*;")
_POINTER_DECL = re.compile(r"^\s*(?:const\s+)?[A-Za-z_]\w*\s*\*\s*(\w+)\s*;")
_PROBE_XML = """<mujoco><custom><numeric name="a" data="1 2 3"/><numeric name="b" data="4"/></custom>
<worldbody><body><joint name="j" type="slide"/><geom size=".1"/></body>
<body><freejoint/><geom size=".1"/></body></worldbody>
<actuator><motor joint="j"/></actuator></mujoco>"""


def _struct_lines(header: str, struct: str) -> list[str]:
    """Declaration lines of `typedef struct <struct>_ { ... } <struct>;`, comments stripped."""
    text = (_INCLUDE / header).read_text()
    body = text.split(f"typedef struct {struct}_ {{", 1)[1].split(f"}} {struct};", 1)[0]
    return [line.split("//", 1)[0] for line in body.splitlines()]


def _leading_sizes(lines: list[str]) -> list[str]:
    """Names of the mjtSize (int64) fields the struct starts with."""
    names = []
    for line in filter(str.strip, lines):
        m = _SIZE_DECL.match(line)
        if not m:
            break
        names.append(m.group(1))
    return names


def _pointer_run(lines: list[str], first: str) -> list[str]:
    """Names of the consecutive pointer fields from `first` on (8 bytes each, no padding)."""
    names: list[str] = []
    for line in filter(str.strip, lines):
        m = _POINTER_DECL.match(line)
        if names and not m:
            break
        if m and (names or m.group(1) == first):
            names.append(m.group(1))
    return names


def _word(address: int) -> int:
    return ctypes.c_int64.from_address(address).value


def _scan(base: int, value: int, start: int = 0, limit: int = 1 << 21) -> int:
    """Byte offset of the first 8-byte word equal to `value` at or after `base + start`.

    Word by word, stopping at the first hit: every word read lies inside the
    struct when the value is one of its own fields.
    """
    for off in range(start, limit, 8):
        if _word(base + off) == value:
            return off
    raise TwinError("native callback: struct field not found in memory")


def _array_address(obj, name: str) -> int | None:
    a = getattr(obj, name, None)
    return a.ctypes.data if isinstance(a, np.ndarray) and a.size > 0 else None


def _pointer_offsets(obj, header: str, struct: str, first: str, anchor: str) -> dict[str, int]:
    """Offsets of the pointer fields of one struct, anchored where `anchor`'s address sits.

    The anchor's address can also be held by an earlier field (`buffer` points
    at the first array, an empty array at the next one), so each hit is tried
    until the whole layout verifies. Hits after the first are only looked for
    within one pointer run of it, which stays inside the struct.
    """
    names = _pointer_run(_struct_lines(header, struct), first)
    value = _array_address(obj, anchor)
    first_hit = _scan(obj._address, value)
    wrong: list[str] = []
    for hit in range(first_hit, first_hit + 8 * len(names), 8):
        if _word(obj._address + hit) != value:
            continue
        offsets = {n: hit + 8 * (i - names.index(anchor)) for i, n in enumerate(names)}
        wrong = _mismatches(obj, offsets)
        if not wrong:
            return offsets
    raise TwinError(f"native callback: {struct} layout does not match {header} ({wrong})")


def _mismatches(obj, offsets: dict[str, int]) -> list[str]:
    """Fields whose pointer is not where `offsets` says.

    Every non-empty array the bindings expose is checked, except NULL struct
    pointers (arena arrays not allocated yet, for which the bindings show a
    placeholder).
    """
    checked, wrong = 0, []
    for name, off in offsets.items():
        addr = _array_address(obj, name)
        word = _word(obj._address + off) if off >= 0 else -1
        if addr is None or word == 0:
            continue
        checked += 1
        if word != addr:
            wrong.append(name)
    return wrong if checked >= 8 else wrong + ["(fewer than 8 fields checked)"]


@lru_cache(maxsize=1)
def size_fields() -> tuple[str, ...]:
    """Names of mjModel's leading integer size fields (nq, nv, nu, ...), from the shipped header."""
    return tuple(_leading_sizes(_struct_lines("mjmodel.h", "mjModel")))


def _size_offsets(model: mujoco.MjModel) -> dict[str, int]:
    """Offsets of the leading int64 size fields of mjModel, each checked against the bindings."""
    offsets = {n: 8 * i for i, n in enumerate(size_fields())}
    checked = [n for n in offsets if hasattr(model, n)]
    for n in checked:
        if _word(model._address + offsets[n]) != int(getattr(model, n)):
            raise TwinError(f"native callback: mjModel.{n} is not at byte {offsets[n]}")
    if not {"nq", "nv", "nu", "nnumeric"} <= set(checked):
        raise TwinError("native callback: mjModel sizes nq, nv, nu, nnumeric not found in mjmodel.h")
    return offsets


@lru_cache(maxsize=1)
def offsets() -> dict[str, int]:
    """Byte offsets of the struct fields the callback reads, keyed 'm.<field>' / 'd.<field>'."""
    model = mujoco.MjModel.from_xml_string(_PROBE_XML)
    data = mujoco.MjData(model)
    sizes = _size_offsets(model)
    m_ptr = _pointer_offsets(model, "mjmodel.h", "mjModel", "buffer", "numeric_data")
    d_ptr = _pointer_offsets(data, "mjdata.h", "mjData", "buffer", "qpos")
    out = {f"m.{n}": sizes[n] for n in ("nq", "nv", "nu", "nnumeric")}
    out.update({f"m.{n}": m_ptr[n] for n in ("numeric_adr", "numeric_size", "numeric_data")})
    out.update({f"d.{n}": d_ptr[n] for n in ("qpos", "qvel", "ctrl", "qfrc_passive", "qfrc_actuator",
                                               "actuator_force")})
    out["d.time"] = _time_offset(data)
    return out


def _time_offset(data: mujoco.MjData) -> int:
    """Byte offset of mjData.time (a double, not a pointer): the word that holds a value set through
    the bindings, checked with a second value."""
    for first in (1234.5678125, 8765.4321875):
        data.time = first
        bits = int(np.array(first).view(np.int64))
        off = _scan(data._address, bits)
        data.time = first + 1.0
        if _word(data._address + off) == int(np.array(first + 1.0).view(np.int64)):
            data.time = 0.0
            return off
    raise TwinError("native callback: mjData.time not found in memory")


# ---------------------------------------------------------------- native code

@intrinsic
def _address(typingctx, ptr):
    """void* → integer address."""
    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.intp))
    return types.intp(types.voidptr), codegen


def _pointer_intrinsic(dtype):
    @intrinsic
    def to_pointer(typingctx, addr):
        """integer address → typed pointer, for numba.carray."""
        sig = types.CPointer(dtype)(types.intp)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
        return sig, codegen
    return to_pointer


@intrinsic
def _fwd_actuation(typingctx, m, d):
    """mj_fwdActuation(m, d), linked by name: the symbol is resolved when the code is loaded
    (`_libmujoco` makes the library's symbols visible), so no address of this process is baked into
    the code and the compiled callback can be cached on disk (an address would differ per process)."""
    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [vp, vp]),
                                            "mj_fwdActuation")
        builder.call(fn, list(args))
        return context.get_dummy_value()
    return types.void(types.voidptr, types.voidptr), codegen


@intrinsic
def _rne(typingctx, m, d, result):
    """mj_rne(m, d, 0, result): the bias forces (Coriolis, centrifugal, gravity) into the nv doubles at
    address `result`, linked by name as `_fwd_actuation` is."""
    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        dp = ir.DoubleType().as_pointer()
        fn = cgutils.get_or_insert_function(builder.module,
                                            ir.FunctionType(ir.VoidType(), [vp, vp, ir.IntType(32), dp]), "mj_rne")
        builder.call(fn, [args[0], args[1], ir.Constant(ir.IntType(32), 0), builder.inttoptr(args[2], dp)])
        return context.get_dummy_value()
    return types.void(types.voidptr, types.voidptr, types.intp), codegen


@intrinsic
def _mul_m(typingctx, m, d, result, vec):
    """mj_mulM(m, d, result, vec): the mass matrix times the nv doubles at `vec`, into `result`."""
    def codegen(context, builder, signature, args):
        vp = ir.IntType(8).as_pointer()
        dp = ir.DoubleType().as_pointer()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [vp, vp, dp, dp]),
                                            "mj_mulM")
        builder.call(fn, [args[0], args[1], builder.inttoptr(args[2], dp), builder.inttoptr(args[3], dp)])
        return context.get_dummy_value()
    return types.void(types.voidptr, types.voidptr, types.intp, types.intp), codegen


_f64_ptr = _pointer_intrinsic(types.float64)
_i64_ptr = _pointer_intrinsic(types.int64)
_i32_ptr = _pointer_intrinsic(types.int32)


@njit(inline="always")
def _field(base, offset):
    """The 8-byte word (size or pointer) at `offset` bytes into a struct."""
    return carray(_i64_ptr(base + offset), 1)[0]


@njit(inline="always")
def _coriolis(M, o, u, v, r):
    """C(ν)ν for the 3×3 row-major matrix M[o:o+9] (coriolis.py's p_u/p_v form)."""
    p_u = M[o] * u + M[o + 1] * v + M[o + 2] * r
    p_v = M[o + 3] * u + M[o + 4] * v + M[o + 5] * r
    return -r * p_v, r * p_u, u * p_v - v * p_u


@njit(inline="always")
def _damping(p, o, u, v, r):
    """D(ν)ν of [Morel-2024 eq. 7] and the speed terms, coefficients p[o:o+19] in Damping.names() order."""
    au, av, ar = abs(u), abs(v), abs(r)
    d00 = -(p[o] + p[o + 1] * au) * (1.0 + p[o + 18] if u < 0.0 else 1.0)
    d11 = -(p[o + 2] + p[o + 3] * av + p[o + 4] * ar + p[o + 14] * au)
    d12 = -(p[o + 5] + p[o + 6] * av + p[o + 7] * ar + p[o + 16] * u)
    d21 = -(p[o + 8] + p[o + 9] * av + p[o + 10] * ar + p[o + 17] * u)
    d22 = -(p[o + 11] + p[o + 12] * av + p[o + 13] * ar + p[o + 15] * au)
    return d00 * u, d11 * v + d12 * r, d21 * v + d22 * r


@njit(inline="always")
def _wind(p, o, wn, we, c, s, u, v):
    """τ_wind (environment.wind_force) with the load p[o:o+6] and the air's NED velocity (wn, we)."""
    u_w = c * wn + s * we
    v_w = -s * wn + c * we
    u_rw, v_rw = u - u_w, v - v_w
    q = 0.5 * RHO_AIR_KG_M3 * (u_rw * u_rw + v_rw * v_rw)
    g = -np.arctan2(v_rw, u_rw)
    return (q * (-p[o + 3] * np.cos(g) * p[o]), q * (p[o + 4] * np.sin(g) * p[o + 1]),
            q * (p[o + 5] * np.sin(2.0 * g) * p[o + 1] * p[o + 2]))


_SW = LAYOUT["switches"].start
_O_MRB, _O_MA, _O_MINV = LAYOUT["M_RB"].start, LAYOUT["M_A"].start, LAYOUT["M_inv"].start
_O_DAMP, _O_WL = LAYOUT["damping"].start, LAYOUT["wind_load"].start
_O_CUR, _O_WIND = LAYOUT["current_ned"].start, LAYOUT["wind_ned"].start
_O_FLAGS, _O_MSW = LAYOUT["flags"].start, LAYOUT["mmg_switches"].start
_O_MMG, _O_FUJI, _O_ADV = LAYOUT["mmg"].start, LAYOUT["fujiwara"].start, LAYOUT["advance"].start
_E_MMG, _E_FUJI = _O_MMG + mmg.SIZE, _O_FUJI + fujiwara.SIZE
_O_SEAL = LAYOUT["sea_load"].start
_mmg_force = njit(mmg.mmg_force)  # the physics functions themselves, compiled
_fujiwara_force = njit(fujiwara.wind_force)


@njit
def hydro_force_body(p, psi, u, v, r, t0, t1, t2, n=0.0, delta=0.0, wn=0.0, we=0.0, thrust_l=0.0, thrust_r=0.0,
                     water_u=0.0, water_v=0.0, sea0=0.0, sea1=0.0, sea2=0.0):
    """Body-frame X of `hydrodynamic_force` (N, N, N m) from the packed parameters `p`, and the
    twin's body-frame acceleration ν̇_r (m/s², m/s², rad/s²) those forces give.

    ν = (u, v, r) in m/s, rad/s; τ = (t0, t1, t2) the actuator force the engine
    applies by itself (it enters only through the exact ν̇_r of added mass); (n, δ)
    the MMG inputs (rps, rad) and (wn, we) the air's NED velocity when the wind comes
    from the controls (flags, see LAYOUT); thrust_l, thrust_r each thruster's actuator force
    (N), on which the advance loss acts. In waves (the 6-DOF hull): (water_u, water_v) the orbital
    velocity of the water at the hull in the body frame (m/s), which damping, the added mass's
    Coriolis and the propellers see the hull move through as they see a current, and (sea0, sea1,
    sea2) the sea's load on surge, sway and yaw (N, N m), which the acceleration the added mass
    answers includes.
    """
    c, s = np.cos(psi), np.sin(psi)
    ur, vr, rr = u, v, r
    if p[_SW + 4] != 0.0:  # current: ν_r = ν − ν_c
        ur = u - (c * p[_O_CUR] + s * p[_O_CUR + 1])
        vr = v - (-s * p[_O_CUR] + c * p[_O_CUR + 1])
    # the rigid body's own Coriolis keeps ν_r (the current); the water's orbital motion is not a
    # steady current and enters where the hull meets the water: damping, C_A, the propellers
    uw, vw = ur - water_u, vr - water_v
    th = p[_SW + 3] != 0.0
    e0, e1, e2 = (t0, t1, t2) if th else (0.0, 0.0, 0.0)
    if th and p[_O_ADV] != 0.0:  # advance loss −c·√|T0|·(u_r − r·y_i), physics/thrusters.py
        loss_l = -p[_O_ADV] * np.sqrt(abs(thrust_l)) * (uw - rr * p[_O_ADV + 1])
        loss_r = -p[_O_ADV] * np.sqrt(abs(thrust_r)) * (uw - rr * p[_O_ADV + 2])
        e0 = e0 + loss_l + loss_r
        e2 = e2 - p[_O_ADV + 1] * loss_l - p[_O_ADV + 2] * loss_r
    if p[_SW + 5] != 0.0:  # wind sees the true velocity ν
        if p[_O_FLAGS + 2] < 0.0:
            wn, we = p[_O_WIND], p[_O_WIND + 1]
        if p[_O_FLAGS + 3] != 0.0:
            w0, w1, w2 = _fujiwara_force(p[_O_FUJI:_E_FUJI], c, s, u, v, wn, we)
        else:
            w0, w1, w2 = _wind(p, _O_WL, wn, we, c, s, u, v)
        e0, e1, e2 = e0 + w0, e1 + w1, e2 + w2
    if p[_O_SEAL] != 0.0:  # a sea known by its mean load (a 3-DOF twin of a log made in waves)
        k0, k1, k2 = seakeeping.known_load(p, psi, uw, _O_SEAL)
        e0, e1, e2 = e0 + k0, e1 + k1, e2 + k2
    if p[_SW + 2] != 0.0:
        d0, d1, d2 = _damping(p, _O_DAMP, uw, vw, rr)
        e0, e1, e2 = e0 - d0, e1 - d1, e2 - d2
    if p[_SW + 1] != 0.0:
        k0, k1, k2 = _coriolis(p, _O_MA, uw, vw, rr)
        if p[_O_FLAGS] == 0.0:  # no Munk moment: the MMG hull's N'_v holds it
            k2 = 0.0
        e0, e1, e2 = e0 - k0, e1 - k1, e2 - k2
    if p[_O_FLAGS + 1] != 0.0:
        m0, m1, m2, _, _ = _mmg_force(p[_O_MMG:_E_MMG], uw, vw, rr, n, delta, p[_O_MSW] != 0.0,
                                      p[_O_MSW + 1] != 0.0, p[_O_MSW + 2] != 0.0)
        e0, e1, e2 = e0 + m0, e1 + m1, e2 + m2
    f0, f1, f2 = (e0 - t0, e1 - t1, e2 - t2) if th else (e0, e1, e2)
    # the twin's ν̇_r = M⁻¹(external − C_RB(ν_r)ν_r), M = M_RB + M_A (M_RB alone without added mass)
    k0, k1, k2 = _coriolis(p, _O_MRB, ur, vr, rr)
    b0, b1, b2 = e0 - k0 + sea0, e1 - k1 + sea1, e2 - k2 + sea2
    m = _O_MINV
    a0 = p[m] * b0 + p[m + 1] * b1 + p[m + 2] * b2
    a1 = p[m + 3] * b0 + p[m + 4] * b1 + p[m + 5] * b2
    a2 = p[m + 6] * b0 + p[m + 7] * b1 + p[m + 8] * b2
    if p[_SW] != 0.0:  # added mass with the exact ν̇_r
        m = _O_MA
        f0 = f0 - (p[m] * a0 + p[m + 1] * a1 + p[m + 2] * a2)
        f1 = f1 - (p[m + 3] * a0 + p[m + 4] * a1 + p[m + 5] * a2)
        f2 = f2 - (p[m + 6] * a0 + p[m + 7] * a1 + p[m + 8] * a2)
    return f0, f1, f2, a0, a1, a2


def _libmujoco() -> ctypes.CDLL:
    """The libmujoco the bindings already loaded (dlopen of the same path returns the same handle)."""
    pkg = Path(mujoco.__file__).resolve().parent
    path = pkg / f"libmujoco.so.{mujoco.__version__}"
    if not path.is_file():
        path = sorted(pkg.glob("libmujoco.so*"))[0]
    lib = ctypes.CDLL(str(path))
    if lib.mj_version() != mujoco.mj_version():
        raise TwinError(f"native callback: {path.name} is not the library the bindings use")
    llvm.load_library_permanently(str(path))  # its symbols for the compiled code (_fwd_actuation)
    return lib


def _source_key() -> int:
    """A positive integer that changes with the source of every module compiled into the callback
    and with the MuJoCo version: part of the disk cache's key."""
    digest = hashlib.sha256(mujoco.__version__.encode())
    for module in (__file__, mmg.__file__, fujiwara.__file__, environment.__file__, waves.__file__,
                   hydrostatics.__file__, seakeeping.__file__):
        digest.update(Path(module).read_bytes())
    return int(digest.hexdigest()[:15], 16) | 1


@njit(inline="always")
def _params(mb, o_nnum, o_nsize, o_ndata, o_nadr, n, magic0, magic1):
    """(is a twin model, its parameters): checks count, size and magic before trusting the data
    (module level, not a closure: the cache keys a closure by what it closes over)."""
    if _field(mb, o_nnum) < 1 or carray(_i32_ptr(_field(mb, o_nsize)), 1)[0] < n:
        return False, carray(_f64_ptr(_field(mb, o_ndata)), 0)
    p = carray(_f64_ptr(_field(mb, o_ndata) + 8 * carray(_i32_ptr(_field(mb, o_nadr)), 1)[0]), n)
    return p[0] == magic0 and p[1] == magic1 and p[2] == n, p


@njit(inline="always")
def _sea(mb, o_nsize, o_ndata, o_nadr, magic, header, nq, nv):
    """The packed sea of numeric 1 when it is one (magic, size, joint addresses in range), else empty."""
    size = carray(_i32_ptr(_field(mb, o_nsize)), 2)[1]
    p = carray(_f64_ptr(_field(mb, o_ndata) + 8 * carray(_i32_ptr(_field(mb, o_nadr)), 2)[1]), max(size, 0))
    if size < header or p[0] != magic or p[1] != size:
        return p[:0]
    for i in range(6):
        if p[26 + i] < 0 or p[26 + i] >= nq or p[32 + i] < 0 or p[32 + i] >= nv:
            return p[:0]
    return p


def _build_callback(six_dof: bool = True):
    """Compile the cfunc with the struct offsets baked in as constants; six_dof=False: without the
    6-DOF hull's terms (its sea's load, its thrust levelled, its inertia on the horizontal joints),
    which numba then never compiles (a quarter of the time), and a 6-DOF model gets no force from it."""
    off = offsets()
    _libmujoco()
    source = _source_key()
    o_nq, o_nv, o_nnum = off["m.nq"], off["m.nv"], off["m.nnumeric"]
    o_nadr, o_nsize, o_ndata = off["m.numeric_adr"], off["m.numeric_size"], off["m.numeric_data"]
    o_qpos, o_qvel, o_pas, o_act = off["d.qpos"], off["d.qvel"], off["d.qfrc_passive"], off["d.qfrc_actuator"]
    o_nu, o_ctrl, o_afrc = off["m.nu"], off["d.ctrl"], off["d.actuator_force"]
    o_q, o_d, n, magic0, magic1 = LAYOUT["qpos_adr"].start, LAYOUT["dof_adr"].start, NPARAM, *MAGIC
    o_flags, o_adv = LAYOUT["flags"].start, LAYOUT["advance"].start
    o_time, sea_magic, sea_header = off["d.time"], seakeeping.SEA_MAGIC, seakeeping.HEADER

    # cached on disk: numba keys a closure's cache by the values it closes over, so other offsets
    # (another MuJoCo) or other physics sources (`source`; numba itself sees only this file's date)
    # compile afresh
    def passive(m, d):
        if source == 0:  # never: `source` is closed over to key the cache, not to be used
            return
        mb, db = _address(m), _address(d)
        ok, p = _params(mb, o_nnum, o_nsize, o_ndata, o_nadr, n, magic0, magic1)
        if not ok:
            return
        nq, nv = _field(mb, o_nq), _field(mb, o_nv)
        qx, qy, qpsi = int(p[o_q]), int(p[o_q + 1]), int(p[o_q + 2])
        dx, dy, dpsi = int(p[o_d]), int(p[o_d + 1]), int(p[o_d + 2])
        if max(qx, qy, qpsi) >= nq or max(dx, dy, dpsi) >= nv or min(qx, qy, qpsi, dx, dy, dpsi) < 0:
            return
        qpos, qvel = carray(_f64_ptr(_field(db, o_qpos)), nq), carray(_f64_ptr(_field(db, o_qvel)), nv)
        psi = qpos[qpsi]
        c, s = np.cos(psi), np.sin(psi)
        u, v = c * qvel[dx] + s * qvel[dy], -s * qvel[dx] + c * qvel[dy]
        _fwd_actuation(m, d)  # actuation comes after passive forces in MuJoCo's pipeline
        fa = carray(_f64_ptr(_field(db, o_act)), nv)
        fn, fe, fy = fa[dx], fa[dy], fa[dpsi]
        # a 6-DOF hull carries its sea as the second numeric (engine/sixdof.py); its thrusters' load
        # on the horizontal joints is put back to the level one the 3-DOF twin applies. A model
        # with a single numeric (the 3-DOF twin) reads and allocates nothing more per step
        six = _field(mb, o_nnum) >= 2
        if six and not six_dof:  # a closed-over constant: numba drops every 6-DOF branch below
            return
        level_n, level_e, level_y = fn, fe, fy
        # in waves the sea's load comes first: the horizontal model sees the water's orbital
        # velocity and accelerates its added mass with the sea's load
        uw, vw, s0, s1, s2 = 0.0, 0.0, 0.0, 0.0, 0.0
        in_sea = False
        if six_dof and six:
            sp = _sea(mb, o_nsize, o_ndata, o_nadr, sea_magic, sea_header, nq, nv)
            if sp.shape[0] > 0:
                ok, ln, le, ly = seakeeping.level_thrust(sp, psi, carray(_f64_ptr(_field(db, o_afrc)),
                                                                         _field(mb, o_nu)))
                if ok:
                    level_n, level_e, level_y = ln, le, ly
                sea_q, water = np.zeros(nv), np.zeros(2)
                seakeeping.sea_load(sp, carray(_f64_ptr(db + o_time), 1)[0], qpos, qvel, sea_q, water)
                uw, vw = c * water[0] + s * water[1], -s * water[0] + c * water[1]
                s0, s1, s2 = c * sea_q[dx] + s * sea_q[dy], -s * sea_q[dx] + c * sea_q[dy], sea_q[dpsi]
                in_sea = True
        t0, t1 = c * level_n + s * level_e, -s * level_n + c * level_e
        n_rps, delta, wn, we = 0.0, 0.0, 0.0, 0.0
        uses_mmg, wind_ctrl = p[o_flags + 1] != 0.0, int(p[o_flags + 2])
        if uses_mmg or wind_ctrl >= 0:
            nu = _field(mb, o_nu)
            if (uses_mmg and nu < 2) or wind_ctrl + 2 > nu:
                return
            ctrl = carray(_f64_ptr(_field(db, o_ctrl)), nu)
            if uses_mmg:
                n_rps, delta = ctrl[0], ctrl[1]
            if wind_ctrl >= 0:
                wn, we = ctrl[wind_ctrl], ctrl[wind_ctrl + 1]
        thrust_l, thrust_r = 0.0, 0.0
        if p[o_adv] != 0.0:
            nu_act = _field(mb, o_nu)
            i_l, i_r = int(p[o_adv + 3]), int(p[o_adv + 4])
            if max(i_l, i_r) >= nu_act or min(i_l, i_r) < 0:
                return
            afrc = carray(_f64_ptr(_field(db, o_afrc)), nu_act)
            thrust_l, thrust_r = afrc[i_l], afrc[i_r]
        x0, x1, x2, a0, a1, a2 = hydro_force_body(p, psi, u, v, qvel[dpsi], t0, t1, level_y, n_rps, delta, wn, we,
                                                  thrust_l, thrust_r, uw, vw, s0, s1, s2)
        qfrc = carray(_f64_ptr(_field(db, o_pas)), nv)
        qfrc[dx] += c * x0 - s * x1 + level_n - fn
        qfrc[dy] += s * x0 + c * x1 + level_e - fe
        qfrc[dpsi] += x2 + level_y - fy
        if six_dof and in_sea:
            # the horizontal joints keep the 3-DOF hull's rigid-body inertia: the 6-DOF body's own
            # on them (its centre of gravity moved fore or aft as it trims, the rates of heave, pitch
            # and roll) is taken off at the 3-DOF twin's own acceleration, a function of the state
            # (MuJoCo solves for the step's after this callback), so that in calm water the 6-DOF
            # hull moves as the 3-DOF twin. The vertical modes keep their coupling to the horizontal
            bias, inertial, acc = np.empty(nv), np.empty(nv), np.zeros(nv)
            _rne(m, d, bias.ctypes.data)
            r = qvel[dpsi]
            an, ae = c * a0 - s * a1 - r * qvel[dy], s * a0 + c * a1 + r * qvel[dx]
            acc[dx], acc[dy], acc[dpsi] = an, ae, a2
            _mul_m(m, d, inertial.ctypes.data, acc.ctypes.data)
            mass = p[_O_MRB]
            xg, yg = p[_O_MRB + 5] / mass, -p[_O_MRB + 2] / mass
            gn, ge = c * xg - s * yg, s * xg + c * yg
            qfrc[dx] += bias[dx] + mass * r * r * gn + inertial[dx] - mass * (an - ge * a2)
            qfrc[dy] += bias[dy] + mass * r * r * ge + inertial[dy] - mass * (ae + gn * a2)
            qfrc[dpsi] += bias[dpsi] + inertial[dpsi] - (mass * (gn * ae - ge * an) + p[_O_MRB + 8] * a2)
            for i in range(nv):
                qfrc[i] += sea_q[i]

    signature = types.void(types.voidptr, types.voidptr)
    try:
        return cfunc(signature, nopython=True, cache=True)(passive)
    except RuntimeError:  # no cache directory numba can write to: compiled for this process alone
        return cfunc(signature, nopython=True)(passive)


@lru_cache(maxsize=2)
def passive_cfunc(six_dof: bool = True):
    """The compiled callback (numba CFunc; `.ctypes` is the function pointer MuJoCo takes);
    six_dof=False: the one for 3-DOF twins alone (_build_callback).

    Compiled on first use (on 2 cores about 5 s for 3-DOF twins alone, 18 s with the 6-DOF hull's
    terms), cached on disk beside this module by numba (later processes load it in well under a
    second) and for the process.
    """
    return _build_callback(six_dof)


def install(six_dof: bool = True) -> None:
    """Install the native callback as MuJoCo's global mjcb_passive (no-op for non-twin models);
    six_dof=False: the one for 3-DOF twins alone."""
    mujoco.set_mjcb_passive(passive_cfunc(six_dof).ctypes)


def is_six_dof(model: mujoco.MjModel) -> bool:
    """Whether the callback treats `model` as a 6-DOF hull (engine/sixdof.py: its sea is a second numeric)."""
    return model.nnumeric >= 2


@contextlib.contextmanager
def installed_native(six_dof: bool = True):
    """Install the native callback for the block, restoring the previous callback after; another
    thread's block waits meanwhile (callbacks.HOOK_LOCK: the callback is one per process). A
    rollout's own threads step inside the block and are not held. six_dof=False, where every model
    of the block is a 3-DOF twin: the callback without the 6-DOF hull's terms, so a process that
    never steps a 6-DOF hull never compiles them."""
    with callbacks.HOOK_LOCK:
        previous = mujoco.get_mjcb_passive()
        install(six_dof)
        try:
            yield
        finally:
            mujoco.set_mjcb_passive(previous)
