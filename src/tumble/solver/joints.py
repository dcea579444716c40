"""Joints: ball, hinge, slider, fixed and distance/rope constraints, solved with the contacts.

Reads body poses and velocities; writes body velocities, the joints' accumulated impulses and,
once per step, `joint_force` / `joint_torque`. One pass costs O(joints).

The scheme is the soft step of Catto (Box2D v3, `joint.c`, `revolute_joint.c`), in 3D, run in
the same substeps as the contacts (see `solver/contacts.py` and `World.step`):
- per substep: warm start (the first substep applies last step's impulses in a pass of its
  own; later ones get the previous substep's through the per-body warm start the relax pass
  sums, as the contacts do), `solve` with bias (soft: the position error is fed back at a rate
  set by a stiffness that is a fraction of the substep rate, `JOINT_HERTZ_PER_SUBSTEP_RATE`),
  integrate positions, `solve` again without bias ("relax"), which removes the push-back
  velocity, so fixing drift adds no energy;
- every row reads the bodies' current poses (positions and orientations after the last
  integration), so the error is exact, not linearised;
- rows of one joint, in order: the axial row (motor or spring, then lower and upper limit),
  solved with the speed and effective mass it has once the block holds, then the angular and
  point rows together as one block (see "a joint's rows as one block").

Rows, with C the position error and J the velocity Jacobian (Cdot = J v):
- point (ball, hinge, fixed): C = p_b - p_a (anchors in world), a 3 x 3 block
  K = (1/m_a + 1/m_b) 1 - [r_a]x I_a^-1 [r_a]x - [r_b]x I_b^-1 [r_b]x, solved at once;
- slider line: the two components of C = p_b - p_a across the axis, with body a's arm
  r_a + d (the point of a under p_b), so that sliding along the axis is free;
- angular lock (fixed, slider): C = 2 vec(q_b f_b (q_a f_a)^-1), K = I_a^-1 + I_b^-1;
- hinge swing: the two components of C = u_a x u_b across u_a (u the hinge axis on each
  body), K the 2 x 2 block of I_a^-1 + I_b^-1 on those directions;
- axial: hinge angle (twist of f_b against f_a about the axis), slider translation along the
  axis, or distance |p_b - p_a|. The motor drives its speed to the target with an impulse
  clamped by max torque (force) times h; a limit is one-sided, speculative when not reached
  (as contacts: it may close the gap in one substep, no more), soft when violated; a distance
  spring of stiffness k [N/m] and damping c [N s/m] is soft with bias rate k / (c + h k) and
  mass scale a / (1 + a), a = h (c + h k) / m_eff (the implicit spring, Box2D's b2MakeSoft
  with omega^2 = k / m_eff, 2 zeta omega = c / m_eff), solved in the pass with bias only (one
  backward-Euler step a substep: numerical damping omega^2 h / 2).

Soft coefficients (as contacts): omega = 2 pi f, a1 = 2 zeta + h omega, a2 = h omega a1,
a3 = 1 / (1 + a2); impulse = -m_eff a2 a3 (Cdot + (omega / a1) C) - a3 * accumulated.
Tuning: `JOINT_HERTZ_PER_SUBSTEP_RATE` 0.25 (twice as stiff as contacts, as in Box2D) with
damping ratio 2 holds a resting chain to micrometres per link at 8 substeps of 1/240 s; more
substeps make every joint stiffer and more exact.

Geometric stiffness: a light link under a large tension T has a stiff "zig-zag" mode (links
turning alternately about their centres, which keeps their anchors together to first order) of
frequency sqrt(2 T r / I), r the anchor arm and I the link's moment. The rows above turn the
constraint direction with the bodies only between substeps, explicitly, so when that frequency
nears the substep rate the mode gains energy: the benchmark's 1,000-link chain of 10 g spheres
(2 T r / I ~ (2,000 rad/s)^2 near the top) had links spinning at 1,200 rad/s after 0.6 s, gained
25 J and drifted 11 mm at 8 substeps (0.5 mm at 16). As with the diagonal geometric-stiffness
terms of Andrews, Teichmann & Kry ("Geometric stiffness for real-time constrained multibody
dynamics", Eurographics 2017), every joint row sees each body's moments raised by h^2 times the
sum of |F| |r| over its joints, F the joints' mean force of the last step (`_finish` sums it
into a per-body `load`). That is the implicit part of the geometric stiffness on the diagonal:
it vanishes as h^2, leaves slow motion alone (a pendulum bob of 0.1 m radius: 7e-4 of its
moment) and damps only the modes near the substep rate. Measured on that chain: drift 2.0 mm,
no energy gained (the scale 1 is needed: at 0.5 it still spun up, 5.6 mm).

Sag, and chains solved exactly: under a steady load F a soft row is a spring of stiffness
m_eff omega^2 (its leak term, impulse scale x accumulated, cancels the warm start), so a joint
carrying F stretches F / (m_eff omega^2) = F h^2 / (m_eff (pi / 2)^2), m_eff the row's own two
bodies': a hanging chain of n 10 g links stretched 2 n g / omega^2 at joint 1 (0.65 mm at 300
links, 2.2 mm at 1,000), and no local stiffness fixes that for every length. Stiffer soft rows
(0.4 of the substep rate) and soft rows without the leak (a per-joint integrator: it
destabilises the chain's slowest modes, whose damping falls as 1 / n^2) blew up; rigid rows
swept by Gauss-Seidel, warm started, blew up on 100 links. So the ball joints are cut into
chains (`ball_chains`: consecutive joints share a body with exactly those two ball joints) and
each chain's point rows are solved exactly in the pass with bias, `_solve_ball_chains`:
A lambda = -(Cdot + b C), A = J M^-1 J^T block tridiagonal (3 x 3 blocks), by block elimination
down the chain and back substitution up it (Thomas' algorithm), O(joints), one thread per chain.
The rows are rigid (no leak, mass scale 1), their error fed back at the soft rows' bias rate b (a
fraction h b = 0.28 of it per substep); the relax pass after the position update is the plain
rigid sweep, which removes the push-back velocity, so fixing drift adds no energy (an exact relax
pass too cost twice as much and let a ragdoll's shoulders drift 0.8 mm at impacts, 0.03 mm
with the sweep). Measured: the hanging 1,000-link chain holds to rounding (0 drift), and falling
from level it drifts 0.45 um (soft rows: 2.0 mm) and keeps its energy (-0.2 J of 396 J kinetic;
soft rows lost 33 J). Chains meet at branch bodies (a ragdoll's torso) through the sweep. A lone ball
joint (its bodies have no other ball joint, or three or more, or it doubles another on the same
pair, like the rope bridge's paired ties) stays a soft row, as do the other kinds' rows: rigid
rows coupled only by the sweep went unstable there too.

Kernels: one solve kernel per joint kind, each launched over the rows of its kind in creation
order (so a pass sweeps the ball joints, then the hinges, ...), all from `_make_solve(kind)`,
whose branches on the kind are resolved when Warp compiles it (`wp.static`): the ball joint's
point row is written out on its own (it warm starts and relaxes every ball joint and solves the
lone ones); the ball joints' chains have `_solve_ball_chains`. Every kernel takes the joint
arrays as one struct, `Joints` (derived from `JOINT_FIELDS`), and the body arrays as the
solver's `BodyArrays`, each built once per set of arrays. No adjoint code is generated.

Joint force: the accumulated impulses are per substep (each substep applies them again as its
warm start), so the step's mean force is the sum of the substeps' final impulses over dt (the
relax pass adds them up); a joint whose mean force exceeds `break_force` breaks at the end of
the step (it stops acting and its bodies collide again).

On the CPU, Warp runs threads in order, so each pass is a Gauss-Seidel sweep in joint order and
the result is deterministic. On CUDA the passes are Jacobi: deltas are added with atomics and
each joint's impulse is scaled by 1 / (largest joint count of its two bodies); a chain is one
thread there too (never run on a GPU).

Jointed pairs do not collide unless the joint says `collide=True`: `JointSet.filter_pairs` drops
them from the broad phase's pair list before the narrow phase (a binary search of each pair in
the sorted keys of such joints, then an order-keeping compaction by exclusive scan).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
import warp as wp

from .. import npmath, validate
from ..errors import TumbleError
from ..launch import LaunchCache, launch
from ..model import Field, Role, body_arrays, fields_of
from ..real import BodyArrays, float_t, mat33, mat33w, quat, vec3, vec3w, wide_t
from ..state import ArraySet, RowGroup, readonly
from ..structs import array_struct, fill_struct
from .rigid import add_to_velocity, inv_inertia_world, safe_inverse

# no adjoint code: nothing differentiates through the joints, and it would double the compile time
wp.set_module_options({"enable_backward": False})

#: joint stiffness as a fraction of the substep rate, and its damping ratio (Box2D v3:
#: joints twice as stiff as contacts, damping ratio 2)
JOINT_HERTZ_PER_SUBSTEP_RATE = 0.25
JOINT_DAMPING_RATIO = 2.0
#: the fastest a joint block's position error is fed back, per row [m/s, rad/s] (as contacts' push-out):
#: errors beyond 5 mm (at 8 substeps of 1/240 s) are closed at this speed. Light bodies pulled apart by
#: joints that cannot all hold (a 4 g sphere between a turning kinematic box and a static body) were
#: flung at the error's full rate and diverged (a random search: 12 of 360 such worlds against 20)
JOINT_PUSH_SPEED = wp.constant(float_t(3.0))


#: anchors closer than this [m] (axes closer than this angle [rad]) are one pivot (`JointSet.pivots`)
PIVOT_TOLERANCE = 1.0e-6


class JointKind(IntEnum):
    """Joint types. `DISTANCE` also covers ropes (min_length 0) and springs."""

    BALL = 0
    HINGE = 1
    SLIDER = 2
    FIXED = 3
    DISTANCE = 4


#: names accepted by `World.add_joint` and scene files ("rope" is a distance joint that only pulls)
JOINT_NAMES = {
    "ball": JointKind.BALL,
    "hinge": JointKind.HINGE,
    "slider": JointKind.SLIDER,
    "fixed": JointKind.FIXED,
    "distance": JointKind.DISTANCE,
    "rope": JointKind.DISTANCE,
}

_M, _S, _X = Role.MODEL, Role.STATE, Role.SCRATCH

#: every per-joint array, declared once (as `tumble.model.BODY_FIELDS` declares the body arrays): the
#: definitions are the model's (`world.model.joints`), what changes while stepping the state's
#: (`world.state.joints`), the step's running sums the solver's scratch
JOINT_FIELDS: tuple[Field, ...] = (
    Field("joint_kind", wp.int32, _M, "", "JointKind"),
    Field("joint_body_a", wp.int32, _M, "", "body row, or -1 for the world (a fixed frame at the origin)"),
    Field("joint_body_b", wp.int32, _M, "", "body row, or -1 for the world"),
    Field("joint_local_a", vec3, _M, "m", "anchor in body a's frame (in the world for the world)"),
    Field("joint_local_b", vec3, _M, "m", "anchor in body b's frame"),
    Field("joint_frame_a", quat, _M, "", "joint frame in body a's frame; its x axis is the hinge / slider axis"),
    Field("joint_frame_b", quat, _M, "", "joint frame in body b's frame"),
    Field("joint_limit", wp.int32, _M, "", "1 = lower/upper rows act"),
    Field("joint_lower", float_t, _M, "", "lower limit: hinge [rad], slider [m], distance: min length [m]"),
    Field("joint_upper", float_t, _M, "", "upper limit: hinge [rad], slider [m], distance: max length [m]"),
    Field("joint_motor", wp.int32, _M, "", "1 = motor acts (hinge, slider)"),
    Field("joint_motor_speed", float_t, _M, "", "motor target speed [rad/s] or [m/s], b relative to a"),
    Field("joint_motor_max", float_t, _M, "", "largest motor torque [N m] or force [N]"),
    Field("joint_length", float_t, _M, "m", "distance: rest length of the spring"),
    Field("joint_stiffness", float_t, _M, "N/m", "distance spring stiffness (0 = none)"),
    Field("joint_damping", float_t, _M, "N s/m", "distance spring damping"),
    Field("joint_break_force", float_t, _M, "N", "the joint breaks above this mean force; inf = unbreakable"),
    Field("joint_collide", wp.int32, _M, "", "1 = the pair still collides"),
    Field("joint_scale", float_t, _M, "", "impulse scale: 1 on the CPU; Jacobi relaxation on CUDA"),
    Field("joint_enabled", wp.int32, _S, "", "1 while acting, 0 once broken"),
    Field("joint_impulse_linear", vec3, _S, "N s", "point / slider-line impulse on b, world (the warm start)"),
    Field("joint_impulse_angular", vec3, _S, "N m s", "angular impulse on b, world"),
    Field("joint_impulse_axial", float_t, _S, "", "motor or spring impulse along the axial row"),
    Field("joint_impulse_lower", float_t, _S, "", "lower limit impulse (>= 0)"),
    Field("joint_impulse_upper", float_t, _S, "", "upper limit impulse (>= 0)"),
    Field("joint_angle", float_t, _S, "rad", "hinge: its angle at the last relax pass, whole turns counted"),
    Field("joint_sum_linear", vec3, _X, "N s", "the step's substep impulses summed, for the step's mean force"),
    Field("joint_sum_angular", vec3, _X, "N m s", "the step's angular substep impulses summed"),
    Field("joint_force", vec3, _S, "N", "mean force on b over the last step, world"),
    Field("joint_torque", vec3, _S, "N m", "mean torque on b over the last step, world"),
)

#: the joint arrays as the kernels take them: `joint_body_a` is `j.body_a`
Joints = array_struct("Joints", fields_of(JOINT_FIELDS), "joint_", __name__)

# the kinds as plain ints, for the compile-time branches (wp.static) of the solve kernels
_BALL, _HINGE, _SLIDER, _FIXED, _DISTANCE = (int(k) for k in JointKind)


# ---------------------------------------------------------------------------- geometry of a joint


@wp.struct
class _Geometry:
    """One joint's rows at the current poses (world frame)."""

    ra: vec3  # anchor offsets from the centres
    rb: vec3
    arm_a: vec3  # where the linear impulse acts on a (r_a; r_a + d for a slider)
    d: vec3  # p_b - p_a
    axis: vec3  # joint axis on a (hinge, slider)
    perp1: vec3  # two directions across the axis
    perp2: vec3
    twist: vec3  # angular error to remove (fixed, slider: all three; hinge: across the axis)
    n: vec3  # axial row: linear direction (slider, distance), zero for the hinge
    ja: vec3  # axial row: angular Jacobian of a (Cdot = n.(v_b - v_a) + jb.w_b - ja.w_a)
    jb: vec3
    value: float_t  # axial coordinate: hinge angle [rad], slider translation [m], distance [m]
    Ia: mat33  # world inverse inertias
    Ib: mat33
    ma: float_t  # inverse masses
    mb: float_t


@wp.func
def _axial_k(g: _Geometry):
    """The axial row's J M^-1 J^T: |n|^2 (1/m_a + 1/m_b) + ja.I_a^-1 ja + jb.I_b^-1 jb."""
    return wp.dot(g.n, g.n) * (g.ma + g.mb) + wp.dot(g.ja, g.Ia * g.ja) + wp.dot(g.jb, g.Ib * g.jb)


@wp.func
def _axial_mass(g: _Geometry):
    """Effective mass of the axial row on its own: 1 / `_axial_k`."""
    k = _axial_k(g)
    if k > float_t(0.0):
        return float_t(1.0) / k
    return float_t(0.0)


@wp.func
def _axial_speed(g: _Geometry, va: vec3, wa: vec3, vb: vec3, wb: vec3):
    return wp.dot(g.n, vb - va) + wp.dot(g.jb, wb) - wp.dot(g.ja, wa)


@wp.struct
class _Velocities:
    va: vec3
    wa: vec3
    vb: vec3
    wb: vec3


@wp.func
def _apply_axial(g: _Geometry, s: _Velocities, impulse: float_t):
    """Velocities after an impulse along the axial row."""
    out = _Velocities()
    out.va = s.va - g.n * (g.ma * impulse)
    out.wa = s.wa - g.Ia * g.ja * impulse
    out.vb = s.vb + g.n * (g.mb * impulse)
    out.wb = s.wb + g.Ib * g.jb * impulse
    return out


@wp.func
def _apply_linear(g: _Geometry, s: _Velocities, P: vec3):
    """Velocities after a linear impulse P on b at its anchor (-P on a at its arm)."""
    out = _Velocities()
    out.va = s.va - P * g.ma
    out.wa = s.wa - g.Ia * wp.cross(g.arm_a, P)
    out.vb = s.vb + P * g.mb
    out.wb = s.wb + g.Ib * wp.cross(g.rb, P)
    return out


@wp.func
def _apply_angular(g: _Geometry, s: _Velocities, L: vec3):
    """Velocities after an angular impulse L on b (-L on a)."""
    out = _Velocities()
    out.va = s.va
    out.wa = s.wa - g.Ia * L
    out.vb = s.vb
    out.wb = s.wb + g.Ib * L
    return out


@wp.func
def _push(bias: vec3):
    """A block's position feedback [m/s, rad/s], each row's at most JOINT_PUSH_SPEED."""
    top = JOINT_PUSH_SPEED
    return vec3(wp.clamp(bias[0], -top, top), wp.clamp(bias[1], -top, top), wp.clamp(bias[2], -top, top))


@wp.struct
class _Pass:
    """A solve pass as a joint's one-sided rows take it: the soft coefficients (see `softness`)."""

    inv_h: float_t  # 1 / substep
    use_bias: int  # 1: the pass with bias; 0: the relax pass
    bias_rate: float_t
    mass_scale: float_t
    impulse_scale: float_t
    relax: float_t  # the joint's impulse scale (1 on the CPU)


@wp.func
def _limit(speed: float_t, mass: float_t, C: float_t, sign: float_t, accumulated: float_t, p: _Pass):
    """New accumulated impulse (>= 0) of a one-sided row keeping C >= 0; `sign` -1 for an upper limit.

    `speed` is the axial row's speed and `mass` its effective mass (as the block sees them, see
    `_Axial`). Speculative while C > 0 (the gap may close within the substep, no more), soft when violated.
    """
    bias = float_t(0.0)
    ms = float_t(1.0)
    isc = float_t(0.0)
    if C > float_t(0.0):
        bias = C * p.inv_h
    elif p.use_bias != 0:
        bias = p.bias_rate * C
        ms = p.mass_scale
        isc = p.impulse_scale
    j = -mass * ms * (sign * speed + bias) - isc * accumulated
    return wp.max(accumulated + j * p.relax, float_t(0.0))


@wp.func
def _total(g: _Geometry, s: _Velocities, linear: vec3, angular: vec3, axial: float_t):
    """Velocities after the joint's whole accumulated impulse (warm start)."""
    out = _apply_linear(g, s, linear)
    out = _apply_angular(g, out, angular)
    return _apply_axial(g, out, axial)


@wp.func
def _solve33(K: mat33, r: vec3):
    if wp.determinant(K) == float_t(0.0):
        return vec3()
    return wp.inverse(K) * r


# ---------------------------------------------------------------------------- a joint's rows as one block
# A hinge's point and swing rows, a fixed joint's point and angular rows, a slider's line and
# angular rows are solved together, as one block: row by row, a body whose moment is small beside
# m r^2 about the anchor (a pendulum's bob) is turned by the angular rows instead of moved, and
# the point row turns it back, so the rows converged at I / (I + m r^2) a pass: a hinged bob of
# r = 2 cm on a 1 m arm, pushed across the hinge plane at 1 m/s, swung 35 mm out of it; welded
# 1 m out, it sagged 25 mm. The axial row (motor, spring, limits) comes first, solved as the
# block will see it (`_Axial`: its speed once the block holds, its mass the Schur complement,
# I + m r^2 for the bob), and the block then takes up rigidly what the axial impulse did to its rows.


@wp.struct
class _Rows:
    """Three rows of a joint, row i: Cdot_i = n_i.(v_b - v_a) + jb_i.w_b - ja_i.w_a (the rows of
    the matrices n, ja, jb); `on` is 1 for a row in use, 0 for one left out (a hinge's third swing
    row, a slider's third line row). A linear group's impulse is sum lambda_i n_i at the anchors,
    an angular group's sum lambda_i ja_i (ja_i = jb_i)."""

    n: mat33
    ja: mat33
    jb: mat33
    C: vec3  # position errors
    on: vec3


@wp.struct
class _Block:
    """A joint's rows solved together: a linear group (point, or slider line) and an angular one
    (hinge swing, or angular lock)."""

    lin: _Rows
    ang: _Rows


@wp.struct
class _Factor:
    """The block's K = [[A, B], [B^T, C]] (A the linear group's 3 x 3, C the angular group's)
    ready to solve: A^-1, B and the inverse of the Schur complement S = C - B^T A^-1 B.

    Worked in float64 in both precisions (`real.wide_t`): K's condition number reaches m r^2 / I,
    6,250 for a 2 cm bob on a 1 m arm, and the axial row's Schur complement against it (`_Axial`)
    is ~1 left of two terms of ~6,250. In float32 that difference came out anywhere from negative
    to 1e-3, so a hinge limit stopped the bob with up to a thousand times its impulse and the
    pendulum flew apart (joint error 6 m); a few dozen float64 operations a joint and pass."""

    A_inv: mat33w
    B: mat33w
    S_inv: mat33w


@wp.func
def _wide_group(x: _Rows):
    """A group's rows, widened: n, ja, jb, on."""
    return mat33w(x.n), mat33w(x.ja), mat33w(x.jb), vec3w(x.on)


@wp.func
def _group_coupling(g: _Geometry, x: _Rows, y: _Rows):
    """J_x M^-1 J_y^T between two groups, masked to the rows in use (in float64, see `_Factor`)."""
    xn, xja, xjb, xon = _wide_group(x)
    yn, yja, yjb, yon = _wide_group(y)
    m = wide_t(g.ma) + wide_t(g.mb)
    K = (xn * wp.transpose(yn)) * m + xja * mat33w(g.Ia) * wp.transpose(yja) + xjb * mat33w(g.Ib) * wp.transpose(yjb)
    return wp.diag(xon) * K * wp.diag(yon)


@wp.func
def _inverse_or_zero(M: mat33w):
    """M^-1; zero when M is singular (rows no body can move along)."""
    if wp.determinant(M) == wide_t(0.0):
        return mat33w()
    return wp.inverse(M)


@wp.func
def _factor(g: _Geometry, blk: _Block):
    """Factor the block's K (the identity on rows left out)."""
    one = vec3w(wide_t(1.0), wide_t(1.0), wide_t(1.0))
    A = _group_coupling(g, blk.lin, blk.lin) + wp.diag(one - vec3w(blk.lin.on))
    C = _group_coupling(g, blk.ang, blk.ang) + wp.diag(one - vec3w(blk.ang.on))
    f = _Factor()
    f.B = _group_coupling(g, blk.lin, blk.ang)
    f.A_inv = _inverse_or_zero(A)
    f.S_inv = _inverse_or_zero(C - wp.transpose(f.B) * f.A_inv * f.B)
    return f


@wp.func
def _block_solve_wide(f: _Factor, r1: vec3w, r2: vec3w):
    """(x, y) with K (x, y) = (r1, r2), by the Schur complement, in float64."""
    y = f.S_inv * (r2 - wp.transpose(f.B) * (f.A_inv * r1))
    x = f.A_inv * (r1 - f.B * y)
    return x, y


@wp.func
def _block_solve(f: _Factor, r1: vec3, r2: vec3):
    """(x, y) with K (x, y) = (r1, r2), in the world's precision."""
    x, y = _block_solve_wide(f, vec3w(r1), vec3w(r2))
    return vec3(x), vec3(y)


@wp.func
def _group_speed(x: _Rows, s: _Velocities):
    return wp.cw_mul(x.n * (s.vb - s.va) + x.jb * s.wb - x.ja * s.wa, x.on)


@wp.func
def _group_apply(g: _Geometry, x: _Rows, s: _Velocities, lam: vec3):
    """Velocities after the group's impulses lam."""
    out = _Velocities()
    out.va = s.va - wp.transpose(x.n) * lam * g.ma
    out.wa = s.wa - g.Ia * (wp.transpose(x.ja) * lam)
    out.vb = s.vb + wp.transpose(x.n) * lam * g.mb
    out.wb = s.wb + g.Ib * (wp.transpose(x.jb) * lam)
    return out


@wp.func
def _block_apply(g: _Geometry, blk: _Block, s: _Velocities, lin: vec3, ang: vec3):
    return _group_apply(g, blk.ang, _group_apply(g, blk.lin, s, lin), ang)


@wp.struct
class _Axial:
    """The axial row (motor, spring, rod, limits) as the block that follows it sees it.

    With the block's rows held (K_bb lambda_b = -(v_b + bias_b) after the axial impulse), an axial
    impulse dl leaves the axial speed at v_ax - u.(v_b + bias_b) + S dl, with c = J_b M^-1 J_ax^T
    the coupling column, u = K_bb^-1 c and S = J_ax M^-1 J_ax^T - c.u the Schur complement: so the
    row is solved with that projected speed and the effective mass 1 / S, an exact solve of the
    joint's rows together with the block (for a hinge: all six). A body whose own moment is small
    beside m r^2 about the hinge (a pendulum's bob) is then stopped by a limit as the whole
    pendulum, not as a spinning ball: with its own mass (1 / I) the limit held a 2 cm bob on a 1 m
    arm for I / (I + m r^2) of its swing and the bob ran through a 45 degree limit to 76 degrees.
    A distance joint has no block: u = 0, S its own row's."""

    u_lin: vec3  # u, in the block's linear and angular groups
    u_ang: vec3
    bias_lin: vec3  # the block's position feedback, this pass
    bias_ang: vec3
    mass: float_t  # 1 / S [kg, kg m^2]


@wp.func
def _axial_coupling(g: _Geometry, x: _Rows):
    """c = J_x M^-1 J_ax^T for the group x and the axial row, masked to the rows in use (float64)."""
    xn, xja, xjb, xon = _wide_group(x)
    c = xn * vec3w(g.n) * (wide_t(g.ma) + wide_t(g.mb)) + xja * (mat33w(g.Ia) * vec3w(g.ja))
    c = c + xjb * (mat33w(g.Ib) * vec3w(g.jb))
    return wp.cw_mul(c, xon)


@wp.func
def _axial_with_block(g: _Geometry, blk: _Block, f: _Factor, bias_lin: vec3, bias_ang: vec3):
    """The axial row coupled to the block (see `_Axial`); its Schur complement in float64 (`_Factor`)."""
    a = _Axial()
    c1 = _axial_coupling(g, blk.lin)
    c2 = _axial_coupling(g, blk.ang)
    u1, u2 = _block_solve_wide(f, c1, c2)
    k = wide_t(_axial_k(g))
    schur = k - wp.dot(c1, u1) - wp.dot(c2, u2)
    if schur > wide_t(1.0e-9) * k:
        a.u_lin = vec3(u1)
        a.u_ang = vec3(u2)
        a.mass = float_t(wide_t(1.0) / schur)
    else:
        # the block alone fixes the axial coordinate (both bodies' rows degenerate): the row on its own
        a.mass = _axial_mass(g)
    a.bias_lin = bias_lin
    a.bias_ang = bias_ang
    return a


@wp.func
def _axial_alone(g: _Geometry):
    """The axial row without a block (distance joints)."""
    a = _Axial()
    a.mass = _axial_mass(g)
    return a


@wp.func
def _projected_speed(g: _Geometry, blk: _Block, a: _Axial, s: _Velocities):
    """The axial speed once the block has held its rows: v_ax - u.(v_b + bias_b)."""
    v = _axial_speed(g, s.va, s.wa, s.vb, s.wb)
    v = v - wp.dot(a.u_lin, _group_speed(blk.lin, s) + a.bias_lin)
    return v - wp.dot(a.u_ang, _group_speed(blk.ang, s) + a.bias_ang)


# ---------------------------------------------------------------------------- kernels


@wp.func
def _inv_inertia_loaded(q: quat, inv_i: vec3, load: float_t, h: float_t):
    """World inverse inertia with the joints' geometric stiffness: each moment I_k gains h^2 load."""
    e = h * h * load
    one = float_t(1.0)
    return inv_inertia_world(
        q, vec3(inv_i[0] / (one + e * inv_i[0]), inv_i[1] / (one + e * inv_i[1]), inv_i[2] / (one + e * inv_i[2]))
    )


@wp.struct
class _Body:
    x: vec3
    q: quat
    v: vec3
    w: vec3
    m: float_t
    I: mat33


@wp.func
def _load(i: int, b: BodyArrays, load: wp.array(dtype=float_t), h: float_t):
    """Pose, velocities and inverse mass / inertia of body row i; the world (-1) is fixed at the origin.

    The inertia carries the joints' geometric stiffness (`_inv_inertia_loaded`).
    """
    s = _Body()
    s.q = wp.quat_identity(dtype=float_t)
    if i >= 0:
        s.x = b.position[i]
        s.q = b.orientation[i]
        s.v = b.velocity[i]
        s.w = b.angular_velocity[i]
        s.m = b.inv_mass[i]
        s.I = _inv_inertia_loaded(b.orientation[i], b.inv_inertia[i], load[i], h)
    return s


@wp.func
def add_velocity(
    i: int,
    dv: vec3,
    dw: vec3,
    v: wp.array(dtype=vec3),
    w: wp.array(dtype=vec3),
    inv_mass: wp.array(dtype=float_t),
    serial: int,
):
    """Add a velocity change to body row i (not the world, not static bodies); atomics off the CPU."""
    if i >= 0:
        if inv_mass[i] != float_t(0.0):
            add_to_velocity(v, w, i, dv, dw, serial)


def _make_solve(kind: int):
    """The solve kernel of one joint kind: the other kinds' rows are left out when Warp compiles it."""

    @wp.func
    def geometry(
        xa: vec3,
        qa: quat,
        xb: vec3,
        qb: quat,
        local_a: vec3,
        local_b: vec3,
        frame_a: quat,
        frame_b: quat,
        ma: float_t,
        mb: float_t,
        Ia: mat33,
        Ib: mat33,
        last: float_t,
    ):
        g = _Geometry()
        ra = wp.quat_rotate(qa, local_a)
        rb = wp.quat_rotate(qb, local_b)
        d = (xb + rb) - (xa + ra)
        fa = qa * frame_a
        fb = qb * frame_b
        one = float_t(1.0)
        zero = float_t(0.0)
        axis = wp.quat_rotate(fa, vec3(one, zero, zero))
        g.ra = ra
        g.rb = rb
        g.d = d
        g.arm_a = ra
        g.axis = axis
        g.perp1 = wp.quat_rotate(fa, vec3(zero, one, zero))
        g.perp2 = wp.quat_rotate(fa, vec3(zero, zero, one))
        g.Ia = Ia
        g.Ib = Ib
        g.ma = ma
        g.mb = mb
        g.n = vec3()
        g.ja = vec3()
        g.jb = vec3()
        g.value = zero
        g.twist = vec3()
        if wp.static(kind == _FIXED or kind == _SLIDER):
            # relative rotation of the frames, world: q_err = f_b f_a^-1 ~ (theta / 2, 1), C = 2 vec(q_err)
            e = fb * wp.quat_inverse(fa)
            s = float_t(2.0)
            if e[3] < zero:
                s = float_t(-2.0)
            g.twist = vec3(e[0], e[1], e[2]) * s
        if wp.static(kind == _HINGE):
            # u_a x u_b is the swing of b's axis away from a's (small angles: the rotation vector across u_a)
            g.twist = wp.cross(axis, wp.quat_rotate(fb, vec3(one, zero, zero)))
            # hinge angle: twist of f_b against f_a about the axis, from q_rel = f_a^-1 f_b, in
            # (-pi, pi]; counted on from the last relax pass's (`last`), whole turns included, so a
            # limit is on the angle turned since creation (as a joint coordinate), not on a wrapped
            # one: an infinite side is no limit (the wrapped angle jumping from -pi to pi read as a
            # 2 rad violation of the other side), and a range may span turns. (A hinge turning more
            # than half a turn within one substep, 1,500 rad/s at the default substep, would lose a turn.)
            rel = wp.quat_inverse(fa) * fb
            turn = float_t(2.0) * wp.atan2(rel[0], rel[3]) - last
            turn = turn - float_t(2.0 * math.pi) * wp.floor((turn + float_t(math.pi)) / float_t(2.0 * math.pi))
            g.value = last + turn
            g.ja = axis
            g.jb = axis
        if wp.static(kind == _SLIDER):
            g.arm_a = ra + d
            g.n = axis
            g.ja = wp.cross(ra + d, axis)
            g.jb = wp.cross(rb, axis)
            g.value = wp.dot(axis, d)
        if wp.static(kind == _DISTANCE):
            length = wp.length(d)
            n = axis  # coincident anchors: any direction will do
            if length > float_t(1.0e-12):
                n = d / length
            g.n = n
            g.ja = wp.cross(ra, n)
            g.jb = wp.cross(rb, n)
            g.value = length
        return g

    @wp.func
    def axial_speed(g: _Geometry, blk: _Block, ax: _Axial, s: _Velocities):
        """The axial row's speed as the block sees it (`_projected_speed`); a distance joint has no block."""
        if wp.static(kind == _DISTANCE):
            return _axial_speed(g, s.va, s.wa, s.vb, s.wb)
        return _projected_speed(g, blk, ax, s)

    @wp.func
    def block(g: _Geometry):
        """The rows solved together: point (world axes) and swing (hinge), point and angular lock
        (fixed, world axes), line (across the axis) and angular lock (slider)."""
        blk = _Block()
        zero = float_t(0.0)
        one = float_t(1.0)
        ex = vec3(one, zero, zero)
        ey = vec3(zero, one, zero)
        ez = vec3(zero, zero, one)
        ones = vec3(one, one, one)
        if wp.static(kind == _HINGE or kind == _FIXED):
            blk.lin.n = wp.identity(n=3, dtype=float_t)
            blk.lin.ja = wp.matrix_from_rows(wp.cross(g.ra, ex), wp.cross(g.ra, ey), wp.cross(g.ra, ez))
            blk.lin.jb = wp.matrix_from_rows(wp.cross(g.rb, ex), wp.cross(g.rb, ey), wp.cross(g.rb, ez))
            blk.lin.C = g.d
            blk.lin.on = ones
        if wp.static(kind == _SLIDER):
            blk.lin.n = wp.matrix_from_rows(g.perp1, g.perp2, vec3())
            blk.lin.ja = wp.matrix_from_rows(wp.cross(g.arm_a, g.perp1), wp.cross(g.arm_a, g.perp2), vec3())
            blk.lin.jb = wp.matrix_from_rows(wp.cross(g.rb, g.perp1), wp.cross(g.rb, g.perp2), vec3())
            blk.lin.C = vec3(wp.dot(g.perp1, g.d), wp.dot(g.perp2, g.d), zero)
            blk.lin.on = vec3(one, one, zero)
        if wp.static(kind == _HINGE):
            blk.ang.ja = wp.matrix_from_rows(g.perp1, g.perp2, vec3())
            blk.ang.jb = blk.ang.ja
            blk.ang.C = vec3(wp.dot(g.perp1, g.twist), wp.dot(g.perp2, g.twist), zero)
            blk.ang.on = vec3(one, one, zero)
        if wp.static(kind == _FIXED or kind == _SLIDER):
            blk.ang.ja = wp.identity(n=3, dtype=float_t)
            blk.ang.jb = blk.ang.ja
            blk.ang.C = g.twist
            blk.ang.on = ones
        return blk

    # a name of its own: a recorded CPU graph finds a kernel by its name
    @wp.kernel(name=f"_solve_{JointKind(kind).name.lower()}")
    def solve(
        rows: wp.array(dtype=wp.int32),
        j: Joints,
        b: BodyArrays,
        load: wp.array(dtype=float_t),
        mode: int,  # 0 warm start, 1 solve with bias, 2 relax (no bias; sums the next warm start)
        h: float_t,
        bias_rate: float_t,
        mass_scale: float_t,
        impulse_scale: float_t,
        serial: int,
        count: int,
    ):
        thread = wp.tid()
        if thread >= count:
            return  # launched over the rows of one kind
        k = rows[thread]
        if j.enabled[k] == 0:
            return
        if wp.static(kind == _BALL):
            # the point row as one soft (or, relaxing, rigid) row; the chains' rows are solved
            # exactly by `_solve_ball_chains` in the pass with bias, the lone ones here
            g = _ball(k, j, b, load, h)
            P0 = j.impulse_linear[k]
            P = P0  # warm start: last step's impulse
            if mode != 0:
                cdot = g.cdot
                ms = float_t(1.0)
                isc = float_t(0.0)
                if mode == 1:
                    cdot = cdot + g.C * bias_rate
                    ms = mass_scale
                    isc = impulse_scale
                P = (-ms * _solve33(_ball_mass(g), cdot) - isc * P0) * j.scale[k]
                j.impulse_linear[k] = P0 + P
            add_velocity(
                g.ia, -P * g.ma, -(g.Ia * wp.cross(g.ra, P)), b.velocity, b.angular_velocity, b.inv_mass, serial
            )
            add_velocity(g.ib, P * g.mb, g.Ib * wp.cross(g.rb, P), b.velocity, b.angular_velocity, b.inv_mass, serial)
            if mode == 2:
                # relax: the impulse is final for the substep and starts the next one (warm start)
                T = P0 + P
                add_velocity(
                    g.ia,
                    -T * g.ma,
                    -(g.Ia * wp.cross(g.ra, T)),
                    b.warm_velocity,
                    b.warm_angular_velocity,
                    b.inv_mass,
                    serial,
                )
                add_velocity(
                    g.ib,
                    T * g.mb,
                    g.Ib * wp.cross(g.rb, T),
                    b.warm_velocity,
                    b.warm_angular_velocity,
                    b.inv_mass,
                    serial,
                )
                j.sum_linear[k] = j.sum_linear[k] + T
        else:
            ia = j.body_a[k]
            ib = j.body_b[k]
            A = _load(ia, b, load, h)
            B = _load(ib, b, load, h)
            g = geometry(
                A.x,
                A.q,
                B.x,
                B.q,
                j.local_a[k],
                j.local_b[k],
                j.frame_a[k],
                j.frame_b[k],
                A.m,
                B.m,
                A.I,
                B.I,
                j.angle[k],
            )
            s0 = _Velocities()
            s0.va = A.v
            s0.wa = A.w
            s0.vb = B.v
            s0.wb = B.w
            s = s0
            zero = float_t(0.0)

            if mode == 0:
                # warm start: last step's impulses, at the current poses
                s = _total(
                    g,
                    s,
                    j.impulse_linear[k],
                    j.impulse_angular[k],
                    j.impulse_axial[k] + j.impulse_lower[k] - j.impulse_upper[k],
                )
            else:
                use_bias = 0
                ms = float_t(1.0)
                isc = zero
                if mode == 1:
                    use_bias = 1
                    ms = mass_scale
                    isc = impulse_scale
                relax = j.scale[k]
                inv_h = float_t(1.0) / h

                # the block's rows (p_b = p_a, or p_b on a's axis line; the frames turning together) and
                # their position feedback, and the axial row as the block sees it (`_Axial`)
                blk = _Block()
                f = _Factor()
                bias1 = vec3()
                bias2 = vec3()
                if wp.static(kind != _DISTANCE):
                    blk = block(g)
                    f = _factor(g, blk)
                    if use_bias != 0:
                        bias1 = _push(wp.cw_mul(blk.lin.C, blk.lin.on) * bias_rate)
                        bias2 = _push(wp.cw_mul(blk.ang.C, blk.ang.on) * bias_rate)
                ax = _axial_alone(g)
                if wp.static(kind == _HINGE or kind == _SLIDER):
                    if j.motor[k] != 0 or j.limit[k] != 0:
                        ax = _axial_with_block(g, blk, f, bias1, bias2)

                # axial: motor or spring, then the limits
                axial = j.impulse_axial[k]
                axial0 = axial + j.impulse_lower[k] - j.impulse_upper[k]
                if j.motor[k] != 0 and (wp.static(kind == _HINGE or kind == _SLIDER)):
                    # drive the joint speed to the target; |impulse| <= max torque (force) * h
                    cdot = axial_speed(g, blk, ax, s) - j.motor_speed[k]
                    cap = j.motor_max[k] * h
                    new = wp.clamp(axial - ax.mass * cdot * relax, -cap, cap)
                    s = _apply_axial(g, s, new - axial)
                    axial = new
                if (
                    wp.static(kind == _DISTANCE)
                    and j.lower[k] < j.upper[k]
                    and (j.stiffness[k] > zero or j.damping[k] > zero)
                    and use_bias != 0
                ):
                    # implicit spring: soft row with bias rate k / (c + h k), a = h (c + h k) / m_eff, in the
                    # pass with bias only: solved again in the relax pass, at the positions already moved by
                    # h v, it took a second backward-Euler step, an extra damping k h (an undamped spring lost
                    # its energy at w^2 h, twice backward Euler's w^2 h / 2; tests/physics/test_independent_checks.py)
                    meff = ax.mass
                    if meff > zero:
                        kc = j.damping[k] + h * j.stiffness[k]
                        a2 = h * kc * safe_inverse(meff)
                        sms = a2 / (float_t(1.0) + a2)
                        sis = float_t(1.0) / (float_t(1.0) + a2)
                        sbias = j.stiffness[k] / kc * (g.value - j.length[k])
                        cdot = axial_speed(g, blk, ax, s)
                        new = axial + (-meff * sms * (cdot + sbias) - sis * axial) * relax
                        s = _apply_axial(g, s, new - axial)
                        axial = new
                if wp.static(kind == _DISTANCE) and j.lower[k] >= j.upper[k]:
                    # rigid rod: C = |d| - length, two-sided
                    bias = zero
                    if use_bias != 0:
                        bias = bias_rate * (g.value - j.lower[k])
                    cdot = axial_speed(g, blk, ax, s)
                    new = axial + (-ax.mass * ms * (cdot + bias) - isc * axial) * relax
                    s = _apply_axial(g, s, new - axial)
                    axial = new
                j.impulse_axial[k] = axial
                # both rows: a range, or (hinge, slider) lower == upper, the joint locked there; a
                # distance joint with lower == upper is the rigid rod above
                ranged = j.lower[k] < j.upper[k]
                if wp.static(kind != _DISTANCE):
                    ranged = j.lower[k] <= j.upper[k]
                if j.limit[k] != 0 and ranged:
                    p = _Pass()
                    p.inv_h = inv_h
                    p.use_bias = use_bias
                    p.bias_rate = bias_rate
                    p.mass_scale = ms
                    p.impulse_scale = isc
                    p.relax = relax
                    lo = j.impulse_lower[k]
                    new = _limit(axial_speed(g, blk, ax, s), ax.mass, g.value - j.lower[k], float_t(1.0), lo, p)
                    s = _apply_axial(g, s, new - lo)
                    j.impulse_lower[k] = new
                    hi = j.impulse_upper[k]
                    new = _limit(axial_speed(g, blk, ax, s), ax.mass, j.upper[k] - g.value, float_t(-1.0), hi, p)
                    s = _apply_axial(g, s, hi - new)
                    j.impulse_upper[k] = new

                # the block: p_b = p_a (hinge, fixed) or p_b on a's axis line (slider), and the
                # bodies' frames turning together (all three axes, or the two across a hinge)
                if wp.static(kind != _DISTANCE):
                    acc1 = wp.cw_mul(blk.lin.n * j.impulse_linear[k], blk.lin.on)  # accumulated impulses
                    acc2 = wp.cw_mul(blk.ang.ja * j.impulse_angular[k], blk.ang.on)
                    r1 = _group_speed(blk.lin, s) + bias1
                    r2 = _group_speed(blk.ang, s) + bias2
                    x1, x2 = _block_solve(f, r1, r2)
                    # the block's impulses are its own part plus -u times the axial impulses (`_Axial`): the
                    # own part is soft (its leak isc acts on acc + u axial0 only), the part the axial rows
                    # make (u dax) is taken up rigidly, as they assumed (soft, a limit's impulse on a light
                    # bob was left as spin)
                    lam1 = (-ms * x1 - isc * (acc1 + ax.u_lin * axial0)) * relax
                    lam2 = (-ms * x2 - isc * (acc2 + ax.u_ang * axial0)) * relax
                    dax = j.impulse_axial[k] + j.impulse_lower[k] - j.impulse_upper[k] - axial0
                    lam1 = lam1 - ax.u_lin * ((float_t(1.0) - ms) * dax)
                    lam2 = lam2 - ax.u_ang * ((float_t(1.0) - ms) * dax)
                    s = _block_apply(g, blk, s, lam1, lam2)
                    j.impulse_linear[k] = wp.transpose(blk.lin.n) * (acc1 + lam1)
                    j.impulse_angular[k] = wp.transpose(blk.ang.ja) * (acc2 + lam2)

            add_velocity(ia, s.va - s0.va, s.wa - s0.wa, b.velocity, b.angular_velocity, b.inv_mass, serial)
            add_velocity(ib, s.vb - s0.vb, s.wb - s0.wb, b.velocity, b.angular_velocity, b.inv_mass, serial)
            if mode == 2:
                # relax: these impulses are final for the substep and start the next one (warm start)
                axial = j.impulse_axial[k] + j.impulse_lower[k] - j.impulse_upper[k]
                t = _total(g, _Velocities(), j.impulse_linear[k], j.impulse_angular[k], axial)
                add_velocity(ia, t.va, t.wa, b.warm_velocity, b.warm_angular_velocity, b.inv_mass, serial)
                add_velocity(ib, t.vb, t.wb, b.warm_velocity, b.warm_angular_velocity, b.inv_mass, serial)
                # and count them towards the step's mean force
                j.sum_linear[k] = j.sum_linear[k] + j.impulse_linear[k] + g.n * axial
                spin = j.impulse_angular[k]
                if wp.static(kind == _HINGE):
                    spin = spin + g.axis * axial  # a hinge's axial row is angular
                    j.angle[k] = g.value  # the angle the next pass counts on from
                j.sum_angular[k] = j.sum_angular[k] + spin

    return solve


# ---------------------------------------------------------------------------- ball joints


@wp.struct
class _Ball:
    """One ball joint's point row at the current poses: bodies, world arms, inverse masses, C and Cdot."""

    ia: int
    ib: int
    ra: vec3
    rb: vec3
    ma: float_t
    mb: float_t
    Ia: mat33
    Ib: mat33
    C: vec3  # p_b - p_a
    cdot: vec3  # its rate
    on: int  # 0 = broken: the row does nothing


@wp.func
def _ball(k: int, j: Joints, b: BodyArrays, load: wp.array(dtype=float_t), h: float_t):
    g = _Ball()
    g.ia = j.body_a[k]
    g.ib = j.body_b[k]
    g.on = j.enabled[k]
    A = _load(g.ia, b, load, h)
    B = _load(g.ib, b, load, h)
    ra = wp.quat_rotate(A.q, j.local_a[k])  # the world (identity pose): its anchor is the world point
    rb = wp.quat_rotate(B.q, j.local_b[k])
    pa = A.x + ra
    pb = B.x + rb
    if g.ia < 0:
        ra = vec3()
    if g.ib < 0:
        rb = vec3()
    g.ra = ra
    g.rb = rb
    g.ma = A.m
    g.mb = B.m
    g.Ia = A.I
    g.Ib = B.I
    g.C = pb - pa
    g.cdot = B.v + wp.cross(B.w, rb) - A.v - wp.cross(A.w, ra)
    return g


@wp.func
def _ball_mass(g: _Ball):
    """K = (1/m_a + 1/m_b) 1 - [r_a]x I_a^-1 [r_a]x - [r_b]x I_b^-1 [r_b]x: Cdot's change per impulse."""
    Sa = wp.skew(g.ra)
    Sb = wp.skew(g.rb)
    return wp.identity(n=3, dtype=float_t) * (g.ma + g.mb) - Sa * g.Ia * Sa - Sb * g.Ib * Sb


@wp.func
def _coupling(g: _Ball, f: _Ball):
    """Change of g's Cdot per impulse of f through the bodies they share:
    sum over shared c of s_g s_f (1/m_c - [r_g]x I_c^-1 [r_f]x) (s = +1 on the joint's b, -1 on its a)."""
    out = mat33()
    if g.on == 0 or f.on == 0:
        return out
    for side in range(2):
        c = g.ia
        rg = g.ra
        m = g.ma
        I = g.Ia
        sg = float_t(-1.0)
        if side == 1:
            c = g.ib
            rg = g.rb
            m = g.mb
            I = g.Ib
            sg = float_t(1.0)
        if c >= 0:
            if f.ia == c:
                out = out - sg * (wp.identity(n=3, dtype=float_t) * m - wp.skew(rg) * I * wp.skew(f.ra))
            if f.ib == c:
                out = out + sg * (wp.identity(n=3, dtype=float_t) * m - wp.skew(rg) * I * wp.skew(f.rb))
    return out


@wp.struct
class _ChainScratch:
    """Scratch of the chains' elimination, one entry per chain slot (`JointSet.refresh` sizes it)."""

    inv_d: wp.array(dtype=mat33)  # the eliminated diagonal block, inverted
    lower: wp.array(dtype=mat33)  # its coupling to the previous slot, A[t, t - 1]
    rhs: wp.array(dtype=vec3)  # the eliminated right-hand side, then the slot's impulse
    arm_a: wp.array(dtype=vec3)  # and the joint's world arms and (loaded) inverse inertias
    arm_b: wp.array(dtype=vec3)
    inertia_a: wp.array(dtype=mat33)
    inertia_b: wp.array(dtype=mat33)


@wp.kernel
def _solve_ball_chains(
    chain_joints: wp.array(dtype=wp.int32),
    chain_start: wp.array(dtype=wp.int32),
    j: Joints,
    b: BodyArrays,
    load: wp.array(dtype=float_t),
    scratch: _ChainScratch,
    h: float_t,
    bias_rate: float_t,
    serial: int,
    count: int,
):
    """The point rows of one chain of ball joints (consecutive joints share a body), solved exactly
    with bias: A lambda = -(Cdot + b C), A = J M^-1 J^T block tridiagonal (3 x 3 blocks: K on the
    diagonal, `_coupling` beside it), by block elimination down the chain and back substitution up it.
    (The relax pass is the plain sweep, the ball kind's solve kernel: the chain is solved again next substep.)
    """
    p = wp.tid()
    if p >= count:
        return
    s = chain_start[p]
    e = chain_start[p + 1]
    one = wp.identity(n=3, dtype=float_t)
    # eliminate down the chain: D_t = A_tt - A_t,t-1 D_t-1^-1 A_t-1,t, y_t = r_t - A_t,t-1 D_t-1^-1 y_t-1
    for t in range(s, e):
        k = chain_joints[t]
        g = _ball(k, j, b, load, h)
        r = -(g.cdot + g.C * bias_rate)
        D = _ball_mass(g)
        B = mat33()
        if t > s:
            # the previous joint as stored: its bodies and arms (the coupling takes the shared bodies' masses from g)
            f = _Ball()
            f.ia = j.body_a[chain_joints[t - 1]]
            f.ib = j.body_b[chain_joints[t - 1]]
            f.on = j.enabled[chain_joints[t - 1]]
            f.ra = scratch.arm_a[t - 1]
            f.rb = scratch.arm_b[t - 1]
            B = _coupling(g, f)
            L = B * scratch.inv_d[t - 1]
            D = D - L * wp.transpose(B)
            r = r - L * scratch.rhs[t - 1]
        if g.on == 0:
            D = one
            r = vec3()
        Dinv = mat33()
        if wp.determinant(D) != float_t(0.0):
            Dinv = wp.inverse(D)
        scratch.inv_d[t] = Dinv
        scratch.lower[t] = B
        scratch.rhs[t] = r
        scratch.arm_a[t] = g.ra
        scratch.arm_b[t] = g.rb
        scratch.inertia_a[t] = g.Ia
        scratch.inertia_b[t] = g.Ib
    # back substitution up the chain: lambda_t = D_t^-1 (y_t - A_t,t+1 lambda_t+1), A_t,t+1 = A_t+1,t^T
    lam = scratch.inv_d[e - 1] * scratch.rhs[e - 1]
    scratch.rhs[e - 1] = lam
    for i in range(e - 1 - s):
        t = e - 2 - i
        lam = scratch.inv_d[t] * (scratch.rhs[t] - wp.transpose(scratch.lower[t + 1]) * lam)
        scratch.rhs[t] = lam
    # apply the impulses
    for t in range(s, e):
        k = chain_joints[t]
        if j.enabled[k] != 0:
            ia = j.body_a[k]
            ib = j.body_b[k]
            ma = float_t(0.0)
            mb = float_t(0.0)
            if ia >= 0:
                ma = b.inv_mass[ia]
            if ib >= 0:
                mb = b.inv_mass[ib]
            ra = scratch.arm_a[t]
            rb = scratch.arm_b[t]
            Ia = scratch.inertia_a[t]
            Ib = scratch.inertia_b[t]
            P = scratch.rhs[t] * j.scale[k]
            j.impulse_linear[k] = j.impulse_linear[k] + P
            add_velocity(ia, -P * ma, -(Ia * wp.cross(ra, P)), b.velocity, b.angular_velocity, b.inv_mass, serial)
            add_velocity(ib, P * mb, Ib * wp.cross(rb, P), b.velocity, b.angular_velocity, b.inv_mass, serial)


#: one solve kernel per joint kind
_SOLVE: dict[JointKind, wp.Kernel] = {kind: _make_solve(int(kind)) for kind in JointKind}


@wp.kernel
def _finish(j: Joints, load: wp.array(dtype=float_t), inv_dt: float_t, count: int):
    k = wp.tid()
    if k >= count:
        return
    # mean force over the step: the substeps' impulses (each acts once per substep) summed, over dt
    f = j.sum_linear[k] * inv_dt
    j.force[k] = f
    j.torque[k] = j.sum_angular[k] * inv_dt
    j.sum_linear[k] = vec3()
    j.sum_angular[k] = vec3()
    if j.enabled[k] == 0:
        return
    # geometric load of the next step: |F| |r| on each body (|r| = |local anchor|, a rotation keeps lengths)
    f_len = wp.length(f)
    if j.body_a[k] >= 0:
        wp.atomic_add(load, j.body_a[k], f_len * wp.length(j.local_a[k]))
    if j.body_b[k] >= 0:
        wp.atomic_add(load, j.body_b[k], f_len * wp.length(j.local_b[k]))
    if f_len > j.break_force[k]:
        j.enabled[k] = 0
        j.impulse_linear[k] = vec3()
        j.impulse_angular[k] = vec3()
        j.impulse_axial[k] = float_t(0.0)
        j.impulse_lower[k] = float_t(0.0)
        j.impulse_upper[k] = float_t(0.0)


@wp.kernel
def _keep_pair(
    pair_a: wp.array(dtype=wp.int32),
    pair_b: wp.array(dtype=wp.int32),
    keys: wp.array(dtype=wp.int64),
    key_joint: wp.array(dtype=wp.int32),
    key_count: int,
    enabled: wp.array(dtype=wp.int32),
    keep: wp.array(dtype=wp.int32),
):
    p = wp.tid()
    a = wp.int64(wp.min(pair_a[p], pair_b[p]))
    b = wp.int64(wp.max(pair_a[p], pair_b[p]))
    key = a * wp.int64(2147483648) + b
    # first key >= key (binary search), then every joint of that pair
    lo = int(0)  # noqa: RUF046, UP018 (a dynamic variable for the loop below, as Warp needs)
    hi = key_count
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    keep[p] = 1
    while lo < key_count:
        if keys[lo] != key:
            break
        if enabled[key_joint[lo]] != 0:
            keep[p] = 0
        lo += 1


@wp.kernel
def _compact_pairs(
    pair_a: wp.array(dtype=wp.int32),
    pair_b: wp.array(dtype=wp.int32),
    keep: wp.array(dtype=wp.int32),
    offset: wp.array(dtype=wp.int32),
    out_a: wp.array(dtype=wp.int32),
    out_b: wp.array(dtype=wp.int32),
):
    p = wp.tid()
    if keep[p] != 0:
        out_a[offset[p]] = pair_a[p]
        out_b[offset[p]] = pair_b[p]


# ---------------------------------------------------------------------------- host side


class _Pairs:
    """A pair list in the broad phase's form (what the narrow phase reads)."""

    def __init__(self, device: str):
        self.pair_a = wp.zeros(1, dtype=wp.int32, device=device)
        self.pair_b = wp.zeros(1, dtype=wp.int32, device=device)
        self.keep = wp.zeros(1, dtype=wp.int32, device=device)  # 1 = the pair stays
        self.offset = wp.zeros(1, dtype=wp.int32, device=device)  # its row in the kept list
        self.pair_count = 0


def softness(h: float) -> tuple[float, float, float]:
    """(bias rate [1/s], mass scale, impulse scale) of the joints' soft rows at substep h [s]."""
    omega = 2.0 * math.pi * JOINT_HERTZ_PER_SUBSTEP_RATE / h
    a1 = 2.0 * JOINT_DAMPING_RATIO + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return omega / a1, a2 * a3, a3


def ball_chains(body_a: np.ndarray, body_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ball joints (rows given by their bodies, -1 the world) cut into chains: (order, starts).

    Consecutive joints of a chain share a body that has exactly these two ball joints (and not
    both bodies), so its J M^-1 J^T is block tridiagonal and positive definite; a chain ends at the
    world, at a body with one ball joint or with three or more (a branch: the chains meeting there
    are coupled by the sweep, in order).
    A closed loop is cut open: its last joint makes a chain of its own. `order` lists positions
    in the given rows, chain after chain; chain c is order[starts[c]:starts[c + 1]].
    """
    m = len(body_a)
    ends = np.concatenate([body_a, body_b]).astype(np.int64)
    joint = np.concatenate([np.arange(m), np.arange(m)])
    real = ends >= 0
    degree = np.bincount(ends[real], minlength=1)
    link = real & (degree[np.maximum(ends, 0)] == 2)
    # the two joints of each body with exactly two are neighbours
    by_body = np.argsort(ends[link], kind="stable")
    pairs = joint[link][by_body].reshape(-1, 2)
    # two joints on the same two bodies are not a chain: their rows are redundant (A singular)
    lo, hi = np.minimum(body_a, body_b), np.maximum(body_a, body_b)
    pairs = pairs[(lo[pairs[:, 0]] != lo[pairs[:, 1]]) | (hi[pairs[:, 0]] != hi[pairs[:, 1]])]
    neighbour = np.full((m, 2), -1, dtype=np.int64)
    for i, j in pairs:  # setup only: a few microseconds a joint
        neighbour[i, int(neighbour[i, 0] >= 0)] = j
        neighbour[j, int(neighbour[j, 0] >= 0)] = i
    seen = np.zeros(m, dtype=bool)
    order, starts = [], [0]
    open_ends = np.flatnonzero(neighbour[:, 1] < 0)
    for first in [*open_ends, *range(m)]:  # chains from their ends, then what is left: loops
        if seen[first]:
            continue
        loop = neighbour[first, 1] >= 0
        previous, current = -1, int(first)
        while current >= 0 and not seen[current]:
            seen[current] = True
            order.append(current)
            a, b = neighbour[current]
            previous, current = current, int(b if a == previous else a)
        if loop and len(order) - starts[-1] > 1:
            starts.append(len(order) - 1)  # the loop's last joint on its own
        starts.append(len(order))
    return np.array(order, dtype=np.int32), np.array(starts, dtype=np.int32)


class JointSet(RowGroup):
    """The joint rows (see JOINT_FIELDS), in creation order, as one table, and the solver's data.

    Its parts share the rows: the definitions (`definitions`, the world's `model.joints`), what
    changes while stepping (`impulses`, the world's `state.joints`) and the step's sums (the
    solver's scratch). Beside them the solver keeps what it derives from the definitions (the
    pair filter's keys, the ball joints' chains) and the per-body geometric load of the last
    step (`_finish` sums it; a resume needs it, so snapshots keep it with the solver).
    """

    def __init__(self, device: str):
        shared: dict[str, wp.array] = {}
        super().__init__(
            *(
                ArraySet(fields_of(JOINT_FIELDS, role), device=device, capacity=16, arrays=shared)
                for role in (Role.MODEL, Role.STATE, Role.SCRATCH)
            )
        )
        self._pairs = _Pairs(device)
        self._keys: wp.array | None = None  # sorted keys of the non-colliding jointed pairs, and their joints
        self._key_joint: wp.array | None = None
        self._key_count = 0
        self._rows: dict[JointKind, wp.array] = {}  # joint rows of each kind present, in creation order
        # the ball joints' chains (`ball_chains`), solved exactly, and those in none, soft (set by `refresh`)
        self._chain_count = self._lone_count = 0
        self._dirty = True
        # the kernels' structs, built once per set of arrays (see `_structs`)
        self._struct: Joints | None = None
        self._bodies: tuple | None = None
        self._chain_scratch: _ChainScratch | None = None

    # -------------------------------------------------------------- building

    @property
    def definitions(self) -> ArraySet:
        """The model's joint rows: kind, bodies, anchors, frames, limits, motors, springs, break force."""
        return self.parts[0]

    @property
    def impulses(self) -> ArraySet:
        """The state's joint rows: accumulated impulses (the warm start), forces, broken flags."""
        return self.parts[1]

    def add(self, rows: dict[str, np.ndarray]) -> range:
        """Append joints given as NumPy rows (see `World.add_joint`); returns their rows."""
        rows = dict(rows)
        k = len(rows["joint_kind"])
        rows.setdefault("joint_enabled", np.ones(k, dtype=np.int32))
        rows.setdefault("joint_scale", np.ones(k))
        out = self.append(rows)
        self._dirty = True
        return out

    def refresh(self, body_count: int) -> None:
        """After joints or body rows changed: the pair filter's keys and the Jacobi scales."""
        if not self._dirty:
            return
        self._dirty = False
        n = self.count
        kinds = self.numpy("joint_kind")
        self._rows = {
            kind: wp.array(np.flatnonzero(kinds == kind).astype(np.int32), dtype=wp.int32, device=self.device)
            for kind in JointKind
            if (kinds == kind).any()
        }
        a = self.numpy("joint_body_a").astype(np.int64)
        b = self.numpy("joint_body_b").astype(np.int64)
        # the ball joints cut into chains, each solved exactly, and the scratch of the elimination; a lone
        # joint (one whose bodies have no other ball joint, or three or more) stays a soft row: rigid rows
        # coupled by the sweep alone, warm started, went unstable (100 links; the rope bridge's paired ties)
        ball = np.flatnonzero(kinds == JointKind.BALL)
        order, starts = ball_chains(a[ball], b[ball])
        size = np.diff(starts)
        chained = np.repeat(size > 1, size)
        chain = ball[order[chained]]
        lone = np.sort(ball[order[~chained]])
        self._chain_count = int((size > 1).sum())
        self._chain_start = self._ints(np.concatenate([[0], np.cumsum(size[size > 1])]))
        self._chain_joints = self._ints(chain)
        slots = max(len(chain), 1)
        self._chain_inv_d = wp.zeros(slots, dtype=mat33, device=self.device)
        self._chain_lower = wp.zeros(slots, dtype=mat33, device=self.device)
        self._chain_rhs = wp.zeros(slots, dtype=vec3, device=self.device)
        self._chain_arm_a = wp.zeros(slots, dtype=vec3, device=self.device)
        self._chain_arm_b = wp.zeros(slots, dtype=vec3, device=self.device)
        self._chain_inertia_a = wp.zeros(slots, dtype=mat33, device=self.device)
        self._chain_inertia_b = wp.zeros(slots, dtype=mat33, device=self.device)
        # (the arrays stay attributes too, so that a recorded graph's key names them)
        self._chain_scratch = fill_struct(_ChainScratch, vars(self), "_chain_")
        self._lone_count = len(lone)
        self._lone_joints = self._ints(lone)
        no_collide = (self.numpy("joint_collide") == 0) & (a >= 0) & (b >= 0)
        lo, hi = np.minimum(a, b)[no_collide], np.maximum(a, b)[no_collide]
        keys = lo * 2147483648 + hi
        order = np.argsort(keys, kind="stable")
        self._key_count = len(keys)
        self._keys = wp.array(np.append(keys[order], 0).astype(np.int64), dtype=wp.int64, device=self.device)
        joint = np.nonzero(no_collide)[0][order]
        self._key_joint = wp.array(np.append(joint, 0).astype(np.int32), dtype=wp.int32, device=self.device)
        if self.device != "cpu" and n:
            # Jacobi on CUDA: divide each joint's impulse by the larger joint count of its bodies
            per_body = np.bincount(np.concatenate([a[a >= 0], b[b >= 0]]), minlength=body_count)
            ca = np.where(a >= 0, per_body[np.maximum(a, 0)], 1)
            cb = np.where(b >= 0, per_body[np.maximum(b, 0)], 1)
            self.write("joint_scale", slice(0, n), 1.0 / np.maximum(np.maximum(ca, cb), 1))

    def held_bodies(self) -> np.ndarray:
        """The body rows some unbroken joint holds, sorted, int32 (read from the device: a copy on CUDA)."""
        if self.count == 0:
            return np.zeros(0, dtype=np.int32)
        on = self.numpy("joint_enabled") != 0
        rows = np.concatenate([self.numpy("joint_body_a")[on], self.numpy("joint_body_b")[on]])
        return np.unique(rows[rows >= 0]).astype(np.int32)

    def pivots(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Of the body rows `rows` (`held_bodies`), those that turn about a point or a line fixed in the
        world, and nothing else: every unbroken joint on them is a ball or a hinge (no limit, no motor) to
        the world, and their anchors share a point (balls alone) or lie on one line (along the hinges' one
        axis, or through two or more balls). Returns (rows, points, axes): the rows, (k,), a point of each
        pivot [m], (k, 3), and its unit axis, (k, 3), zero for a point (the body turns about any axis).
        (Read from the device: a copy on CUDA.)"""
        none = (np.zeros(0, dtype=np.int32), np.zeros((0, 3)), np.zeros((0, 3)))
        if self.count == 0 or len(rows) == 0:
            return none
        a, b = self.numpy("joint_body_a"), self.numpy("joint_body_b")
        on = self.numpy("joint_enabled") != 0
        kind = self.numpy("joint_kind")
        free = (self.numpy("joint_limit") == 0) & (self.numpy("joint_motor") == 0)
        world_a = a < 0
        point = np.where(world_a[:, None], self.numpy("joint_local_a"), self.numpy("joint_local_b"))
        frame = np.where(world_a[:, None], self.numpy("joint_frame_a"), self.numpy("joint_frame_b"))
        found = []
        for row in rows:
            mine = on & ((a == row) | (b == row))
            if not mine.any():
                continue
            ok = mine & ((a < 0) | (b < 0)) & free & ((kind == JointKind.BALL) | (kind == JointKind.HINGE))
            if (mine & ~ok).any():
                continue  # another joint, a limit or a motor: the stretch limit leaves the body to them
            pts = point[mine]
            hinge = kind[mine] == JointKind.HINGE
            axis = np.zeros(3)
            if hinge.any():
                axes = np.array([npmath.quat_rotate(q, (1.0, 0.0, 0.0)) for q in frame[mine][hinge]])
                axis = axes[0] / np.linalg.norm(axes[0])
                if (
                    np.linalg.norm(np.cross(axes, axis), axis=1).max()
                    > PIVOT_TOLERANCE * np.linalg.norm(axes, axis=1).max()
                ):
                    continue  # hinges about different axes hold the body still
            else:
                spread = pts - pts[0]
                far = np.linalg.norm(spread, axis=1)
                if far.max() > PIVOT_TOLERANCE:
                    axis = spread[np.argmax(far)] / far.max()  # balls at two points or more: the line through them
            off = pts - pts[0]
            if np.linalg.norm(off - np.outer(off @ axis, axis), axis=1).max() > PIVOT_TOLERANCE:
                continue  # anchors off one line (or, balls alone, off one point): the body cannot turn
            found.append((row, pts[0], axis))
        if not found:
            return none
        return (
            np.array([f[0] for f in found], dtype=np.int32),
            np.array([f[1] for f in found], dtype=np.float64),
            np.array([f[2] for f in found], dtype=np.float64),
        )

    def _ints(self, values: np.ndarray) -> wp.array:
        """An int32 array on the device (one spare entry: never empty)."""
        return wp.array(np.append(values, 0).astype(np.int32), dtype=wp.int32, device=self.device)

    def remap_bodies(self, slot: np.ndarray) -> None:
        """The body rows were renumbered (row i is now `slot[i]`, -1 if removed): follow them."""
        for name in ("joint_body_a", "joint_body_b"):
            rows = self.numpy(name).astype(np.int64)
            self.write(name, slice(0, self.count), np.where(rows >= 0, slot[np.maximum(rows, 0)], -1))
        self._dirty = True

    # -------------------------------------------------------------- stepping

    def filter_pairs(self, pairs, bodies):
        """The broad phase's pairs without the jointed pairs that do not collide (order kept)."""
        if self.count == 0:
            return pairs
        self.refresh(bodies.count)
        n = pairs.pair_count
        if self._key_count == 0 or n == 0:
            return pairs
        dev = self.device
        out = self._pairs
        if out.pair_a.shape[0] < n:
            out.pair_a = wp.zeros(n, dtype=wp.int32, device=dev)
            out.pair_b = wp.zeros(n, dtype=wp.int32, device=dev)
            out.keep = wp.zeros(n, dtype=wp.int32, device=dev)
            out.offset = wp.zeros(n, dtype=wp.int32, device=dev)
        wp.launch(
            _keep_pair,
            dim=n,
            device=dev,
            inputs=[
                pairs.pair_a,
                pairs.pair_b,
                self._keys,
                self._key_joint,
                self._key_count,
                self.arrays["joint_enabled"],
                out.keep,
            ],
        )
        wp.utils.array_scan(out.keep, out.offset, inclusive=False)
        wp.launch(
            _compact_pairs,
            dim=n,
            device=dev,
            inputs=[pairs.pair_a, pairs.pair_b, out.keep, out.offset, out.pair_a, out.pair_b],
        )
        last = out.offset[n - 1 : n].numpy()[0] + out.keep[n - 1 : n].numpy()[0]
        out.pair_count = int(last)
        return out

    def struct(self) -> Joints:
        """The joint arrays as the kernels take them, built again only when the arrays were."""
        if self._struct is None or self._struct.enabled is not self.arrays["joint_enabled"]:
            self._struct = fill_struct(Joints, self.arrays, "joint_")
        return self._struct

    def _body_struct(self, bodies) -> BodyArrays:
        """The body arrays as the kernels take them, built again only when the arrays were."""
        self._bodies = body_arrays(bodies, self._bodies)
        return self._bodies[0]

    def _launch(self, bodies, h: float, mode: int, cache: LaunchCache | None) -> None:
        """One pass: the joints of each kind present, kind by kind (each in creation order)."""
        j, b = self.struct(), self._body_struct(bodies)
        load = bodies.arrays["body_joint_load"]  # last step's, in the State: a resume needs it
        serial = 1 if self.device == "cpu" else 0
        soft = softness(h)
        for kind, rows in self._rows.items():
            count = rows.shape[0]
            if kind == JointKind.BALL and mode == 1:
                # chains of ball joints, each solved exactly (rigid rows, their error fed back at the soft rate),
                # then the lone ones as soft rows; the relax pass sweeps every ball joint
                if self._chain_count:
                    chains = (self._chain_joints, self._chain_start)
                    count = self._chain_count
                    args = [*chains, j, b, load, self._chain_scratch, h, soft[0], serial, count]
                    launch(_solve_ball_chains, count, args, self.device, cache)
                rows, count = self._lone_joints, self._lone_count
                if count == 0:
                    continue
            launch(_SOLVE[kind], count, [rows, j, b, load, mode, h, *soft, serial, count], self.device, cache)

    def warm_start(self, bodies, h: float, cache: LaunchCache | None = None) -> None:
        """Apply last step's impulses (first substep only; later ones warm start through the relax pass)."""
        if self.count:
            self.refresh(bodies.count)
            self._launch(bodies, h, 0, cache)

    def solve(self, bodies, h: float, *, use_bias: bool, cache: LaunchCache | None = None) -> None:
        """One Gauss-Seidel sweep over the joints: with bias (soft push-back) or without (relax)."""
        if self.count:
            self._launch(bodies, h, 1 if use_bias else 2, cache)

    def finish(self, bodies, dt: float, cache: LaunchCache | None = None) -> None:
        """Joint forces and torques, the mean over the step of `dt` seconds; joints over their break force
        break; each body's geometric load (`body_joint_load`) for the next step."""
        if self.count == 0:
            return
        load = bodies.arrays["body_joint_load"]
        load.zero_()
        launch(_finish, self.capacity, [self.struct(), load, 1.0 / dt, self.count], self.device, cache)

    # -------------------------------------------------------------- views

    def view(self, name: str) -> np.ndarray:
        return readonly(self.numpy(name))


# ---------------------------------------------------------------------------- building one joint


class JointArgumentError(TumbleError, ValueError):
    """A bad argument of `World.add_joint`; `key` names it (scene files report it as the table's key). A
    TumbleError, as every error Tumble raises on purpose is (`except tumble.TumbleError` missed it)."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key
        self.reason = message


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def _quat_conj(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return _quat_mul(_quat_mul(q, np.append(v, 0.0)), _quat_conj(q))[:3]


def _quat_from_x(axis: np.ndarray) -> np.ndarray:
    """Unit quaternion rotating +x onto the unit vector `axis`."""
    c = float(axis[0])
    if c < -1.0 + 1e-12:
        return np.array([0.0, 0.0, 1.0, 0.0])
    q = np.array([0.0, -axis[2], axis[1], 1.0 + c])
    return q / np.linalg.norm(q)


def _point(value, key: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise JointArgumentError(key, f"must be 3 finite numbers, got {value!r}")
    return a


def _scalar(value, key: str, *, low: float | None = None, allow_inf: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise JointArgumentError(key, f"must be a number, got {value!r}") from None
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise JointArgumentError(key, f"must be finite, got {value!r}")
    if low is not None and v < low:
        raise JointArgumentError(key, f"must be >= {low:g}, got {value!r}")
    return v


@dataclass(frozen=True)
class JointBody:
    """What building a joint needs of one of its bodies: row (-1 = world), pose, whether it moves."""

    row: int
    position: np.ndarray
    orientation: np.ndarray
    dynamic: bool

    @staticmethod
    def world() -> JointBody:
        return JointBody(-1, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), False)


def joint_rows(
    kind,
    a: JointBody,
    b: JointBody,
    *,
    anchor=None,
    anchor_a=None,
    anchor_b=None,
    axis=None,
    frame: str = "world",
    lower=None,
    upper=None,
    motor_speed=None,
    max_torque=None,
    max_force=None,
    length=None,
    min_length=None,
    max_length=None,
    stiffness=0.0,
    damping=0.0,
    break_force=math.inf,
    collide: bool = False,
) -> dict[str, np.ndarray]:
    """One joint's rows for `JointSet.add`, checked; see `World.add_joint` for the arguments."""
    if isinstance(kind, str):
        if kind not in JOINT_NAMES:
            raise JointArgumentError("kind", f"unknown joint kind {kind!r}: expected one of {', '.join(JOINT_NAMES)}")
        name, kind = kind, JOINT_NAMES[kind]
    elif isinstance(kind, JointKind):
        name = kind.name.lower()
    else:  # None, a number, True: the kinds are named
        raise JointArgumentError("kind", f"must be one of {', '.join(map(repr, JOINT_NAMES))}, got {kind!r}")
    if frame not in ("world", "body"):
        raise JointArgumentError("frame", f"must be 'world' or 'body', got {frame!r}")
    if a.row >= 0 and a.row == b.row:
        raise JointArgumentError("body_b", "a joint needs two different bodies, got the same body twice")
    if not a.dynamic and not b.dynamic:
        raise JointArgumentError(
            "body_b", "neither body is dynamic (each is static, kinematic or the world): the joint would do nothing"
        )

    # anchors: one shared world point, or one per body (world points, or body-frame points with frame="body")
    if frame == "body" and anchor is not None:
        raise JointArgumentError("anchor", "is a world point; with frame='body' give anchor_a and anchor_b")
    shared = None if anchor is None else _point(anchor, "anchor")
    local: list[np.ndarray | None] = []
    for key, body, given in (("anchor_a", a, anchor_a), ("anchor_b", b, anchor_b)):
        p: np.ndarray | None
        if given is not None:
            p = _point(given, key)
            if frame == "world":
                p = _rotate(_quat_conj(body.orientation), p - body.position)
        elif shared is not None:
            p = _rotate(_quat_conj(body.orientation), shared - body.position)
        elif frame == "body" or kind != JointKind.DISTANCE:
            p = np.zeros(3) if frame == "body" else None
        else:
            p = np.zeros(3)  # a distance joint defaults to the centres
        local.append(p)
    if local[0] is None and local[1] is None:
        local = [np.zeros(3), _rotate(_quat_conj(b.orientation), a.position - b.position)]  # at a's centre
    elif local[0] is None:
        assert local[1] is not None  # not both None
        world_b = b.position + _rotate(b.orientation, local[1])
        local[0] = _rotate(_quat_conj(a.orientation), world_b - a.position)
    elif local[1] is None:
        world_a = a.position + _rotate(a.orientation, local[0])
        local[1] = _rotate(_quat_conj(b.orientation), world_a - b.position)
    assert local[0] is not None and local[1] is not None
    pa = a.position + _rotate(a.orientation, local[0])
    pb = b.position + _rotate(b.orientation, local[1])

    # joint frame: x along the axis (world axis, or in a's frame with frame="body"); fixed: the bodies' frames
    u = np.array([0.0, 0.0, 1.0]) if axis is None else _point(axis, "axis")
    if validate.is_zero(u):
        raise JointArgumentError("axis", "must not be the zero vector")
    u = validate.unit(u)
    if frame == "body":
        u = _rotate(a.orientation, u)
    world_frame = _quat_from_x(u) if kind in (JointKind.HINGE, JointKind.SLIDER) else np.array([0.0, 0.0, 0.0, 1.0])
    frame_a = _quat_mul(_quat_conj(a.orientation), world_frame)
    frame_b = _quat_mul(_quat_conj(b.orientation), world_frame)

    # limits, motor, distance
    limit = 0
    lo, hi = 0.0, 0.0
    if kind in (JointKind.HINGE, JointKind.SLIDER):
        if lower is not None or upper is not None:
            limit = 1
            # a hinge's angle counts whole turns from creation: any range, an infinite side no limit
            lo = -math.inf if lower is None else _scalar(lower, "lower", allow_inf=True)
            hi = math.inf if upper is None else _scalar(upper, "upper", allow_inf=True)
            if lo > hi:
                raise JointArgumentError("lower", f"lower {lo:g} > upper {hi:g}")
    elif lower is not None or upper is not None:
        raise JointArgumentError("lower", f"a {name} joint has no lower/upper limits (hinge and slider do)")
    motor = 0
    speed = top = 0.0
    if motor_speed is not None or max_torque is not None or max_force is not None:
        if kind not in (JointKind.HINGE, JointKind.SLIDER):
            raise JointArgumentError("motor_speed", f"a {name} joint has no motor (hinge and slider do)")
        motor = 1
        speed = _scalar(0.0 if motor_speed is None else motor_speed, "motor_speed")
        key, cap = ("max_torque", max_torque) if kind == JointKind.HINGE else ("max_force", max_force)
        if cap is None:
            raise JointArgumentError(key, f"a {name} motor needs {key}")
        top = _scalar(cap, key, low=0.0, allow_inf=True)
    k = _scalar(stiffness, "stiffness", low=0.0)
    c = _scalar(damping, "damping", low=0.0)
    rest = float(np.linalg.norm(pb - pa))
    if kind == JointKind.DISTANCE:
        rest = rest if length is None else _scalar(length, "length", low=0.0)
        # defaults: a rope is slack up to its length, a spring free, a plain distance joint a rigid rod
        rope, spring = name == "rope", k > 0.0 or c > 0.0
        hi = (
            (math.inf if spring and not rope else rest)
            if max_length is None
            else _scalar(max_length, "max_length", low=0.0, allow_inf=True)
        )
        lo = (
            (0.0 if rope or spring else min(rest, hi))
            if min_length is None
            else _scalar(min_length, "min_length", low=0.0)
        )
        if lo > hi:
            raise JointArgumentError("min_length", f"min_length {lo:g} > max_length {hi:g}")
        limit = 1
    else:
        for key, value in (("length", length), ("min_length", min_length), ("max_length", max_length)):
            if value is not None:
                raise JointArgumentError(key, f"a {name} joint has no {key} (distance and rope joints do)")
        if k or c:
            raise JointArgumentError("stiffness", f"a {name} joint has no spring (distance joints do)")
    force = _scalar(break_force, "break_force", low=0.0, allow_inf=True)
    if force == 0.0:
        raise JointArgumentError("break_force", "must be > 0 (a joint of break force 0 would break at once)")
    big = 1.0e30  # infinite limits as large finite numbers: no inf * 0 in the kernels
    return {
        "joint_kind": np.array([int(kind)], dtype=np.int32),
        "joint_body_a": np.array([a.row], dtype=np.int32),
        "joint_body_b": np.array([b.row], dtype=np.int32),
        "joint_local_a": local[0][None],
        "joint_local_b": local[1][None],
        "joint_frame_a": frame_a[None],
        "joint_frame_b": frame_b[None],
        "joint_limit": np.array([limit], dtype=np.int32),
        "joint_lower": np.array([max(lo, -big)]),
        "joint_upper": np.array([min(hi, big)]),
        "joint_motor": np.array([motor], dtype=np.int32),
        "joint_motor_speed": np.array([speed]),
        "joint_motor_max": np.array([min(top, big)]),
        "joint_length": np.array([rest]),
        "joint_stiffness": np.array([k]),
        "joint_damping": np.array([c]),
        "joint_break_force": np.array([min(force, big)]),
        "joint_collide": np.array([int(bool(collide))], dtype=np.int32),
    }


def joint_error(joints: JointSet, bodies) -> np.ndarray:
    """Position error of each joint [m], shape (j,): the anchors' separation (point joints), its part
    across the axis (slider), or the length outside [min, max] (distance); 0 for broken joints."""
    n = joints.count
    if n == 0:
        return np.zeros(0)
    x = np.vstack([bodies.numpy("body_position"), np.zeros((1, 3))])  # row -1 is the world
    q = np.vstack([bodies.numpy("body_orientation"), [[0.0, 0.0, 0.0, 1.0]]])
    ia, ib = joints.numpy("joint_body_a"), joints.numpy("joint_body_b")
    pa = x[ia] + _rotate_rows(q[ia], joints.numpy("joint_local_a"))
    pb = x[ib] + _rotate_rows(q[ib], joints.numpy("joint_local_b"))
    d = pb - pa
    err = np.linalg.norm(d, axis=1)
    kind = joints.numpy("joint_kind")
    slider = kind == JointKind.SLIDER
    if slider.any():
        fa = _quat_rows(q[ia], joints.numpy("joint_frame_a"))
        axis = _rotate_rows(fa, np.tile([1.0, 0.0, 0.0], (n, 1)))
        across = d - axis * np.einsum("ij,ij->i", d, axis)[:, None]
        err = np.where(slider, np.linalg.norm(across, axis=1), err)
    distance = kind == JointKind.DISTANCE
    if distance.any():
        out = np.maximum(joints.numpy("joint_lower") - err, err - joints.numpy("joint_upper"))
        err = np.where(distance, np.maximum(out, 0.0), err)
    return np.where(joints.numpy("joint_enabled") != 0, err, 0.0)


def _quat_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamilton products of (n, 4) quaternions (x, y, z, w)."""
    av, aw = a[:, :3], a[:, 3:]
    bv, bw = b[:, :3], b[:, 3:]
    return np.hstack([aw * bv + bw * av + np.cross(av, bv), aw * bw - np.einsum("ij,ij->i", av, bv)[:, None]])


def _rotate_rows(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise rotation of vectors v (n, 3) by unit quaternions q (n, 4): v + 2 w (u x v) + 2 u x (u x v)."""
    u, w = q[:, :3], q[:, 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)
