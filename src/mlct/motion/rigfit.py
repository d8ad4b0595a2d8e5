"""One rotation fit for every rig format: joint positions -> a rigid skeleton's local rotations.

A rig file (BVH, glTF/GLB, VRM Animation, SMPL parameters) moves a skeleton whose bones keep
their length, by a root translation and one local rotation per joint a frame. mlct motions are
joint positions, and a generated motion's bones stretch by a few millimetres from frame to frame.
`fit_rig` turns one into the other, once, for every writer:

- bone lengths: fixed over the clip, the motion's median (or lengths the caller gives, e.g. a
  target rig's); rest offsets point along the rig's rest pose (`rest_directions`: the skeleton's
  own standing pose, or a preset's T- or A-pose, rigs.py). A joint with several children (the
  pelvis, the upper spine) turns them as one rigid group, so their offsets are the group's mean
  shape over the clip (generalized Procrustes) turned onto the rest pose;
- the root: translated along the input's root trajectory exactly, turned by the least-squares
  rotation (Kabsch, `kabsch`) of its group; a multi-child joint likewise;
- limbs (hip-knee-ankle, shoulder-elbow-wrist) by two-bone inverse kinematics: the knee (elbow)
  lies in the plane of the input's hip, knee and ankle, placed so that the ankle (wrist) lands
  exactly on the input's whenever the fixed-length leg can reach it. So a planted foot stays
  where the input planted it. A fixed-length foot cannot keep both its ankle and its toe
  where a stretching input foot has them: the ankle is aimed so that whichever of heel and
  toe moves less stays exact (the toe at push-off, the heel at heel strike). Near a straight
  leg the exact solution is ill-conditioned (a leg 2 mm shorter than the input's reach must bend its knee
  out by ~3 cm: the "knee pop" of IK rigs), so the knee moves at most LIMB_TOLERANCE of the
  thigh's length plus, for legs, BEND_SHARE of the input's bend (its knee's distance from the
  hip-ankle line) from where plain aiming puts it: a bent leg gets exact IK (feet touch the
  ground; hands rarely hold anything, so arms keep the tighter bound), a straight one plain aiming,
  where the ankle is off by about the leg's stretch, along the leg (vertical for a standing
  leg, so no sliding either);
- other one-child joints: the shortest turn, in the parent's frame, aiming the bone from the
  joint as already rebuilt (so errors do not add up along a chain); childless joints keep their
  parent's rotation;
- twist: positions cannot tell a bone's spin about itself. The shortest turn from the rest
  direction has none, but it flips by up to 180 degrees in one frame as the bone passes the
  direction opposite its rest (an arm raised overhead from a hanging rest), which a character's
  mesh shows as a snapping twist. The fit adds the twist that continues the previous frame's
  rotation (a parallel transport: it has a closed form per frame, so it is vectorized) and lets
  it leak back to zero with a time constant of TWIST_RELAX_SECONDS: smooth over time, and the
  plain shortest turn wherever nothing flips. Twist never moves a joint.

Rotation math: Kabsch over all frames at once is `kabsch`; the shortest turn between two
vectors and a turn about an axis are mlct.motion.quaternion's. No scipy here: importing its
Rotation or ndimage loads scipy.spatial and scipy.sparse, ~0.4 s of every one-off `mlct
generate --out x.bvh` (bench/cold_start.py), for a turn about an axis and a moving average.
Everything here is in the skeleton's units and its frame (y up, facing +Z); writers convert axes
and units (rigs.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mlct.errors import MlctError
from mlct.motion.rotations import qbetween, quat_to_matrix, rotvec_to_matrix
from mlct.motion.skeleton import Skeleton

PROCRUSTES_ITERATIONS = 3  # mean shape of a multi-child group: converges in 2 on real motion
LIMB_TOLERANCE = 0.01  # of the upper bone: how far IK may move a knee or elbow from plain aiming
BEND_SHARE = 0.2  # ... plus, for legs (contacts), this share of the input's bend
FOOT_WINDOW_SECONDS = 0.25  # smoothing of the foot speeds that choose heel or toe
TWIST_RELAX_SECONDS = 1.0  # a flip's 180 degrees unwind at <= 180 degrees a second


@dataclass(frozen=True)
class RigFit:
    """A motion on a rigid skeleton: FK of (offsets, root, local) gives `positions` exactly."""

    parents: tuple[int, ...]  # -1 for the root
    order: tuple[int, ...]  # joints depth first from the root (parents before children)
    offsets: np.ndarray  # (J, 3) rest offsets from each joint's parent (root: 0)
    root: np.ndarray  # (T, 3) root positions
    local: np.ndarray  # (T, J, 3, 3) rotations in the parent's frame (root: world)
    positions: np.ndarray  # (T, J, 3) the fitted skeleton's joints (FK of the above)

    @property
    def world(self) -> np.ndarray:
        """(T, J, 3, 3) world rotations."""
        return forward(self.parents, self.order, self.offsets, self.root, self.local)[1]

    @property
    def lengths(self) -> np.ndarray:
        """(J,) bone lengths (root: 0)."""
        return np.linalg.norm(self.offsets, axis=-1)


def children_of(parents: tuple[int, ...] | list[int]) -> list[list[int]]:
    children: list[list[int]] = [[] for _ in parents]
    for joint, parent in enumerate(parents):
        if parent >= 0:
            children[parent].append(joint)
    return children


def depth_first(children: list[list[int]], root: int = 0) -> tuple[int, ...]:
    order, stack = [], [root]
    while stack:
        joint = stack.pop()
        order.append(joint)
        stack.extend(reversed(children[joint]))
    return tuple(order)


def forward(parents, order, offsets: np.ndarray, root: np.ndarray,
            local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics: (J, 3) offsets, (T, 3) root, (T, J, 3, 3) local rotations ->
    (T, J, 3) positions and (T, J, 3, 3) world rotations."""
    positions = np.empty(local.shape[:2] + (3,))
    world = np.empty_like(local)
    for joint in order:
        parent = parents[joint]
        if parent < 0:
            positions[:, joint], world[:, joint] = root, local[:, joint]
        else:
            world[:, joint] = world[:, parent] @ local[:, joint]
            positions[:, joint] = positions[:, parent] + world[:, parent] @ offsets[joint]
    return positions, world


def kabsch(source: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(k, 3) vectors and (T, k, 3) targets -> (T, 3, 3) rotations R minimizing |R s - t|^2.

    Kabsch's solution, all frames at once: R = V diag(1, 1, d) U^T from the SVD U S V^T of the
    cross-covariance sum_k s t^T, d = det(V U^T) keeping R a rotation. Written out rather than
    taken from roma (whose import brings torch._dynamo: ~1 s of every export's start) or
    scipy's Rotation.align_vectors (one frame a call: ~80 us each)."""
    u, _, vt = np.linalg.svd(np.einsum("ki,tkj->tij", source, targets))
    v = np.swapaxes(vt, -1, -2)
    flip = np.where(np.linalg.det(v @ np.swapaxes(u, -1, -2)) < 0, -1.0, 1.0)
    v[..., 2] *= flip[:, None]
    return v @ np.swapaxes(u, -1, -2)


def swing(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(T, 3), (T, 3) -> (T, 3, 3) shortest rotations turning `current` towards `target`."""
    return quat_to_matrix(qbetween(current, target))


def group_offsets(bones: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(T, k, 3) bones of one multi-child joint, (k, 3) rest offsets -> (k, 3) offsets: the mean
    shape of the group over time (generalized Procrustes), turned to the rest pose."""
    shape = rest
    for _ in range(PROCRUSTES_ITERATIONS):
        rot = kabsch(shape, bones)  # (T, 3, 3)
        shape = np.einsum("tji,tkj->ki", rot, bones) / len(bones)  # mean of R^T b
    return shape @ kabsch(shape, rest[None])[0].T


def limbs(skeleton: Skeleton) -> dict[int, int]:
    """Two-bone limbs as {middle joint: end joint}: the knees (from the foot joints) and the
    elbows (the last three joints of every chain that starts above the root: the arms)."""
    parents = skeleton.parents
    out = {parents[ankle]: ankle for ankle in (skeleton.foot_left[0], skeleton.foot_right[0])}
    for chain in skeleton.kinematic_chain:
        if chain[0] != 0 and len(chain) >= 3:
            out[chain[-2]] = chain[-1]
    return out


def two_bone_middle(start: np.ndarray, middle: np.ndarray, end: np.ndarray, upper: float,
                    lower: float) -> np.ndarray:
    """(T, 3) where the middle joint of a two-bone limb goes: `upper` from `start` and `lower`
    from `end` (or on the line to it when out of reach), on the side of the input's `middle`."""
    reach = end - start
    dist = np.linalg.norm(reach, axis=-1, keepdims=True)
    axis = reach / np.maximum(dist, 1e-12)
    dist = np.clip(dist, abs(upper - lower) + 1e-9, upper + lower)
    along = (upper**2 - lower**2 + dist**2) / (2 * dist)  # law of cosines
    height = np.sqrt(np.maximum(upper**2 - along**2, 0.0))
    pole = middle - start
    pole = pole - np.sum(pole * axis, axis=-1, keepdims=True) * axis
    norm = np.linalg.norm(pole, axis=-1, keepdims=True)
    # A straight input limb has no bending side: there the middle joint stays on the line.
    pole = np.where(norm > 1e-9, pole / np.maximum(norm, 1e-12), 0.0)
    return start + along * axis + height * pole


def foot_targets(x: np.ndarray, skeleton: Skeleton, offsets: np.ndarray,
                 fps: float) -> np.ndarray:
    """(T, J, 3) where each joint is aimed: the input, except the ankles. A fixed-length foot
    cannot keep both its ankle and its toe where a stretching input foot has them, so the ankle
    goes where the slower of the two stays exact: the heel while it is planted and the toe
    rolls, the toe while it is planted and the heel lifts (w below, from the input's speeds
    over FOOT_WINDOW_SECONDS); the other end is off by the foot's stretch, along it."""
    aims = x.copy()
    window = max(1, int(round(FOOT_WINDOW_SECONDS * fps)))
    for ankle, toe in (skeleton.foot_left, skeleton.foot_right):
        length = float(np.linalg.norm(offsets[toe]))
        foot = x[:, toe] - x[:, ankle]
        toe_first = x[:, toe] - foot * length / np.maximum(
            np.linalg.norm(foot, axis=-1, keepdims=True), 1e-12)  # the ankle if the toe is exact
        if len(x) < 2:
            continue
        speed = [np.linalg.norm(np.diff(x[:, j], axis=0), axis=-1) for j in (ankle, toe)]
        speed = [moving_average(np.concatenate([s[:1], s]), window)
                 for s in speed]  # (T,) per frame
        w = speed[0] / (speed[0] + speed[1] + 1e-4 * length)  # 1: the ankle moves, toe still
        aims[:, ankle] = (1 - w)[:, None] * x[:, ankle] + w[:, None] * toe_first
    return aims


def _twist_angles(local: np.ndarray, axis: np.ndarray, fps: float) -> np.ndarray:
    """(T, 3, 3) shortest-turn local rotations of a one-child joint, (3,) unit rest direction of
    its bone -> (T,) twist angles about that direction that keep the rotation smooth (module doc).

    Twisting by phi about the axis, L(phi) = L Rot(axis, phi), the phi nearest to the previous
    frame's rotation differs from the previous phi by the twist part of N = L_{t-1}^T L_t:
    delta = atan2(tr(N [a]x), tr N - a^T N a); the sum of the deltas carries the rotation
    through a flip, and a leaky sum lets it unwind."""
    step = np.swapaxes(local[:-1], -1, -2) @ local[1:]  # (T-1, 3, 3)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                      [-axis[1], axis[0], 0.0]])
    sin = np.einsum("tij,ji->t", step, cross)
    cos = np.trace(step, axis1=-2, axis2=-1) - np.einsum("i,tij,j->t", axis, step, axis)
    delta = np.arctan2(sin, cos)  # the twist nearest to the previous frame's rotation
    keep = float(np.exp(-1.0 / (TWIST_RELAX_SECONDS * fps)))
    return np.concatenate([[0.0], _leaky_sum(delta, keep)])


def _leaky_sum(x: np.ndarray, keep: float) -> np.ndarray:
    """y[n] = keep (x[n] + y[n - 1]), y[-1] = 0: scipy.signal.lfilter([keep], [1, -keep], x) as
    a loop over a clip's frames (microseconds), without scipy.signal's ~0.7 s import."""
    out, total = np.empty(len(x)), 0.0
    for n, value in enumerate(x):
        total = keep * (value + total)
        out[n] = total
    return out


def moving_average(x: np.ndarray, size: int) -> np.ndarray:
    """(T,) -> (T,) the mean over a window of `size` samples, the edges held outward: what
    scipy.ndimage.uniform_filter1d(x, size, mode="nearest") gives (the window of sample i runs
    from i - size // 2), without scipy's import."""
    left = size // 2
    padded = np.concatenate([np.full(left, x[0]), x, np.full(size - 1 - left, x[-1])])
    total = np.concatenate([[0.0], np.cumsum(padded)])
    return (total[size:] - total[:-size]) / size


def _axis_rotation(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(T, 3, 3) turns by `angles` (T,) radians about the unit `axis` (3,)."""
    return rotvec_to_matrix(angles[:, None] * axis[None])


def check_joints(joints: np.ndarray, skeleton: Skeleton, what: str = "rig export") -> np.ndarray:
    """(T, J, 3) finite float64 joints of `skeleton`; a one-line MlctError otherwise."""
    joints = np.asarray(joints)
    if joints.ndim != 3 or joints.shape[1:] != (skeleton.n_joints, 3) or len(joints) == 0:
        raise MlctError(f"{what} needs joints of shape (frames, {skeleton.n_joints}, 3) for "
                        f"skeleton {skeleton.name!r}, got {joints.shape}")
    if joints.dtype.kind not in "fiu" or not np.isfinite(joints).all():
        raise MlctError(f"{what}: the joints contain NaN or inf values")
    return joints.astype(np.float64)


def column_median(x: np.ndarray) -> np.ndarray:
    """np.median(x, axis=0), to the bit, without the import of numpy.ma that np.median makes
    for its NaN check (~10 ms of a one-off .bvh export): the middle of each sorted column, or
    the mean of the middle two; NaN where a column holds one."""
    if len(x) == 0:
        return np.median(x, axis=0)
    ordered = np.sort(x, axis=0)  # NaN last
    middle = len(x) // 2
    median = ordered[middle] if len(x) % 2 else (ordered[middle - 1] + ordered[middle]) / 2
    return np.where(np.isnan(ordered[-1]), ordered[-1], median)


def fit_rig(joints: np.ndarray, skeleton: Skeleton, rest_directions: np.ndarray | None = None,
            lengths: np.ndarray | None = None, fps: float | None = None) -> RigFit:
    """Fit (T, J, 3) joint positions (skeleton units) to a rigid skeleton (module doc).

    rest_directions: (J, 3) bone directions of the rest pose (default: the skeleton's own);
    lengths: (J,) bone lengths (default: the motion's median); fps: for the twist's time
    constant (default: the skeleton's)."""
    x = check_joints(joints, skeleton)
    rest = np.asarray(skeleton.rest_directions if rest_directions is None else rest_directions,
                      dtype=np.float64)
    rate = float(skeleton.fps if fps is None else fps)
    n_frames = len(x)
    parents = skeleton.parents
    children = children_of(parents)
    order = depth_first(children)
    ends = limbs(skeleton)

    bones = x - x[:, [max(p, 0) for p in parents]]  # (T, J, 3); root: 0
    if lengths is None:
        lengths = column_median(np.linalg.norm(bones, axis=-1))  # (J,)
    lengths = np.asarray(lengths, dtype=np.float64)
    offsets = rest * lengths[:, None]
    for kids in children:
        if len(kids) > 1:  # the group's mean shape, each bone at its length
            shape = group_offsets(bones[:, kids], offsets[kids])
            offsets[kids] = shape / np.maximum(np.linalg.norm(shape, axis=-1, keepdims=True),
                                               1e-12) * lengths[kids, None]
    offsets[0] = 0.0

    aims = foot_targets(x, skeleton, offsets, rate)
    identity = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
    world = np.empty((n_frames, skeleton.n_joints, 3, 3))
    local = np.empty_like(world)
    fitted = x.copy()  # positions as the fitted skeleton rebuilds them, filled in order
    for joint in order:
        parent = parents[joint]
        parent_rot = identity if parent < 0 else world[:, parent]
        kids = children[joint]
        if not kids:
            world[:, joint] = parent_rot
        elif len(kids) == 1:
            kid = kids[0]
            target = aims[:, kid]
            if kid in ends:  # two-bone limb: aim the upper bone where the end can be reached
                upper = float(np.linalg.norm(offsets[kid]))
                solved = two_bone_middle(fitted[:, joint], x[:, kid], aims[:, ends[kid]], upper,
                                         float(np.linalg.norm(offsets[ends[kid]])))
                aimed = x[:, kid] - fitted[:, joint]
                aimed = fitted[:, joint] + aimed * upper / np.maximum(
                    np.linalg.norm(aimed, axis=-1, keepdims=True), 1e-12)
                move = solved - aimed
                size = np.linalg.norm(move, axis=-1, keepdims=True)
                # the input's bend: how far its knee is off the hip-ankle line
                line = aims[:, ends[kid]] - fitted[:, joint]
                line = line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-12)
                off = x[:, kid] - fitted[:, joint]
                bend = np.linalg.norm(off - np.sum(off * line, -1, keepdims=True) * line,
                                      axis=-1, keepdims=True)
                legs = ends[kid] in (skeleton.foot_left[0], skeleton.foot_right[0])
                allowed = LIMB_TOLERANCE * upper + (BEND_SHARE * bend if legs else 0.0)
                target = aimed + move * np.minimum(1.0, allowed / np.maximum(size, 1e-12))
            current = np.einsum("tij,j->ti", parent_rot, offsets[kid])
            turn = np.swapaxes(parent_rot, -1, -2) @ swing(current, target - fitted[:, joint]) \
                @ parent_rot  # the shortest turn, in the parent's frame
            axis = offsets[kid] / max(float(np.linalg.norm(offsets[kid])), 1e-12)
            twisted = turn @ _axis_rotation(axis, _twist_angles(turn, axis, rate))
            world[:, joint] = parent_rot @ twisted
        else:
            world[:, joint] = kabsch(offsets[kids], x[:, kids] - fitted[:, joint, None])
        local[:, joint] = world[:, joint] if parent < 0 else \
            np.swapaxes(parent_rot, -1, -2) @ world[:, joint]
        for kid in kids:
            fitted[:, kid] = fitted[:, joint] + world[:, joint] @ offsets[kid]
    positions, _ = forward(parents, order, offsets, x[:, 0], local)
    return RigFit(parents=parents, order=order, offsets=offsets, root=x[:, 0].copy(),
                  local=local, positions=positions)
