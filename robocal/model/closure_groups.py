"""A closed chain's closures grouped by kind, and their rows at many configurations at once.

`closure_state` is what one Newton step of the batched assembly (robocal.model.closed_chain_batch) needs at
a stack of configurations: the closure vector c, its derivative on the solved coordinates C_s, and per
group the derivatives D1, D2 of the rows w.r.t. LOCAL twists of the anchors and E = D Ad(oMf^-1) w.r.t.
world twists (what the parameter Jacobian needs). Closures of one kind are stacked, so one group costs
one set of array operations whatever the number of its closures.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robocal.model.closure_arrays import closure_arrays, hinge_bases
from robocal.model.lie_arrays import cross
from robocal.model.tree_arrays import TreeArrays


@dataclass
class ClosureGroup:
    """The closures of one kind, stacked: their rows in c, anchor frames and joints, anchor placements on
    those joints, which solved coordinates move each anchor, and the kind's constants."""

    kind: str
    rows: np.ndarray                  # (k * rows,) row indices into the closure vector
    frames: tuple[list, list]         # anchor frame ids (frame 1s, frame 2s)
    joints: tuple[np.ndarray, np.ndarray]
    placements: tuple                 # ((k, 3, 3), (k, 3)) per side
    masks: tuple[np.ndarray, np.ndarray]   # (k, 1, n_solved) 1.0 where the solved coordinate moves the anchor
    length: np.ndarray                # (k,) distance kind's target lengths
    axis: np.ndarray                  # (k, 3) revolute kind's hinge axes
    basis: np.ndarray                 # (k, 2, 3) directions of the hinge misalignment rows

    @property
    def in_order(self) -> bool:
        """Whether the group's rows are all the rows, in order."""
        return bool(np.array_equal(self.rows, np.arange(len(self.rows))))


def with_placements(groups: list[ClosureGroup], model) -> list[ClosureGroup]:
    """The groups with their anchors' placements read from `model` (same frames, another parameter vector)."""
    frames = model.frames
    return [replace(g, placements=tuple((np.array([frames[f].placement.rotation for f in side]),
                                         np.array([frames[f].placement.translation for f in side]))
                                        for side in g.frames)) for g in groups]


def closure_groups(model, loops, tree: TreeArrays) -> list[ClosureGroup]:
    frames, solved = model.frames, loops.solved_v
    starts = np.cumsum([0] + [c.rows for c in loops.closures])
    groups = []
    for kind in dict.fromkeys(c.kind for c in loops.closures):
        ks = [k for k, c in enumerate(loops.closures) if c.kind == kind]
        closures = [loops.closures[k] for k in ks]
        ids = tuple([model.getFrameId(getattr(c, f"frame{s}")) for c in closures] for s in (1, 2))
        joints = tuple(np.array([frames[f].parentJoint for f in side]) for side in ids)
        placements = tuple((np.array([frames[f].placement.rotation for f in side]),
                            np.array([frames[f].placement.translation for f in side])) for side in ids)
        masks = tuple(np.array([np.isin(solved, tree.support_v[j]) for j in js], dtype=float)[:, None, :]
                      for js in joints)
        axes = np.array([c.axis if c.axis is not None else (1.0, 0.0, 0.0) for c in closures], dtype=float)
        groups.append(ClosureGroup(kind, np.concatenate([np.arange(starts[k], starts[k + 1]) for k in ks]), ids,
                                   joints, placements, masks, np.array([c.length for c in closures]), axes,
                                   hinge_bases(axes)))
    return groups


def anchor_frame_columns(P_frame: dict, fids, ccols: np.ndarray):
    """(columns (k, f) among ccols padded with len(ccols), F (k, 6, f)): the anchor frames' own placement
    columns (P_frame: frame id -> its LOCAL twists per free parameter), or None when no anchor of the list has any."""
    used = [np.flatnonzero(np.any(P_frame[f] != 0.0, axis=0)) if f in P_frame else np.zeros(0, dtype=int)
            for f in fids]
    width = max(len(u) for u in used)
    if width == 0:
        return None
    cols = np.full((len(fids), width), len(ccols), dtype=int)
    F = np.zeros((len(fids), 6, width))
    for k, (f, u) in enumerate(zip(fids, used)):
        cols[k, :len(u)] = np.searchsorted(ccols, u)
        F[k, :, :len(u)] = P_frame[f][:, u]
    return cols, F


def to_world(D: np.ndarray, R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """D Ad(M^-1) for M = (R, p): a derivative w.r.t. M's LOCAL twist turned into one w.r.t. a world twist.
    Ad(M^-1) = [[R^T, -R^T [p]x], [0, R^T]], so the two halves are Dv R^T and Dw R^T - (Dv R^T) [p]x, whose
    rows are e [p]x = (e x p)^T."""
    Ev = np.einsum("nij,nkj->nik", D[..., :3], R)
    out = np.empty(D.shape)
    out[..., :3] = Ev
    out[..., 3:] = np.einsum("nij,nkj->nik", D[..., 3:], R) - cross(Ev, p[:, None, :])
    return out


def anchor_poses(g: ClosureGroup, R: np.ndarray, p: np.ndarray):
    """((R1, p1), (R2, p2)): world poses of the group's anchors, (n k, 3, 3) and (n k, 3), sample-major."""
    n, k = len(R), len(g.length)
    poses = []
    for js, (Rf, pf) in zip(g.joints, g.placements):
        Rj = R[:, js]
        Ra = Rj if not (Rf - np.eye(3)).any() else Rj @ Rf       # anchors often sit unrotated on their link
        pa = p[:, js] if not pf.any() else p[:, js] + np.einsum("nkij,kj->nki", Rj, pf)
        poses.append((Ra.reshape(n * k, 3, 3), pa.reshape(n * k, 3)))
    return poses


def group_rows(g: ClosureGroup, poses):
    """c, D1, D2 of the group at its anchor poses (closure_arrays with the kind's constants)."""
    (R1, p1), (R2, p2) = poses
    n = len(R1) // len(g.length)
    if g.kind == "revolute":
        constants = dict(axis=np.tile(g.axis, (n, 1)), basis=np.tile(g.basis, (n, 1, 1)))
    else:
        constants = dict(length=np.tile(g.length, n)) if g.kind == "distance" else {}
    return closure_arrays(g.kind, R1, p1, R2, p2, **constants)


def row_masks(masks: np.ndarray, rows: int) -> np.ndarray:
    """(k rows, n_solved): per-closure column masks (k, 1, n_solved) repeated on each of a closure's rows."""
    return np.repeat(masks, rows, axis=1).reshape(-1, masks.shape[2])


def closure_state(tree: TreeArrays, groups: list[ClosureGroup], n_rows: int, solved: np.ndarray,
                  q: np.ndarray) -> dict:
    """At configurations q (n, nq): world placements of every joint R, p, the solved coordinates' world motion
    columns W (n, 6, n_solved), c (n, n_rows) and C_s = dc/dv on the solved coordinates (n, n_rows, n_solved)."""
    R, p = tree.placements(q)
    W = tree.motion_columns(R, p, solved)
    n, ns = len(q), len(solved)
    pieces = [(g,) + group_state(g, R, p, W) for g in groups]
    # the outputs are allocated last: a large block held while the temporaries come and go makes the
    # allocator map fresh pages for them (measured: twice the time)
    if len(pieces) == 1 and pieces[0][0].in_order:
        return {"R": R, "p": p, "W": W, "c": pieces[0][1].reshape(n, n_rows),
                "Cs": pieces[0][2].reshape(n, n_rows, ns)}
    c, Cs = np.empty((n, n_rows)), np.empty((n, n_rows, ns))
    for g, ck, Ck in pieces:
        c[:, g.rows] = ck.reshape(n, -1)
        Cs[:, g.rows] = Ck.reshape(n, -1, ns)
    return {"R": R, "p": p, "W": W, "c": c, "Cs": Cs}


def group_state(g: ClosureGroup, R: np.ndarray, p: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(c (n, k, rows), C_s (n, k rows, n_solved)) of one group at the joints' world placements R, p and the
    solved coordinates' world motion columns W."""
    n, k = len(R), len(g.length)
    poses = anchor_poses(g, R, p)
    (R1, p1), (R2, p2) = poses
    if g.kind == "point":
        # c = R1^T (p2 - p1); a world twist (v, w) of the body carrying anchor i moves the world point p2
        # by v + w x p2 (seen from either body), so dc = R1^T (u2 - u1), R1^T (v + w x p2) = [R1^T, -B] (v, w)
        # with B = R1^T [p2]x, whose rows are (rows of R1^T) x p2: no 6x6 algebra per anchor
        R1t = np.swapaxes(R1.reshape(n, k, 3, 3), -1, -2)
        ck = np.einsum("nkij,nkj->nki", R1t, (p2 - p1).reshape(n, k, 3))
        E = np.empty((n, k, 3, 6))
        E[..., :3] = R1t
        cross(p2.reshape(n, k, 1, 3), R1t, out=E[..., 3:])       # -B: rows p2 x (rows of R1^T)
        # one (3 k x 6) (6 x ns) product per sample (not k small ones), masked in place: a fresh temporary
        # of this size costs more than the product (measured 65 against 735 us for 256 samples)
        Ck = E.reshape(n, 3 * k, 6) @ W
        Ck *= row_masks(g.masks[1] - g.masks[0], 3)
        return ck, Ck
    ck, D1, D2 = group_rows(g, poses)
    r = ck.shape[1]
    # a coordinate that does not move an anchor contributes nothing: mask the product's columns
    Ck = to_world(D1, R1, p1).reshape(n, k * r, 6) @ W
    Ck *= row_masks(g.masks[0], r)
    C2 = to_world(D2, R2, p2).reshape(n, k * r, 6) @ W
    C2 *= row_masks(g.masks[1], r)
    Ck += C2
    return ck, Ck


def parameter_rows(g: ClosureGroup, R: np.ndarray, p: np.ndarray, sides, frames, nc: int) -> np.ndarray:
    """(n, k * rows, nc): the group's rows' derivative w.r.t. the parameters (nc compact columns), joints held.

    sides: per side (anchor of each pair (P,), the pair's columns (P, c) among the nc, padded with nc, and
    U (n, P, 6, c) the world twists of a joint supporting that anchor's body), or Nones;
    frames: per side (columns (k, f) among the nc, padded with nc; F (k, 6, f) LOCAL twists of each anchor
    frame per column: its own placement parameters), or None."""
    n, k = len(R), len(g.length)
    poses = anchor_poses(g, R, p)
    (R1, p1), (R2, p2) = poses
    point = g.kind == "point"
    if point:
        R1t = np.swapaxes(R1.reshape(n, k, 3, 3), -1, -2)
    else:
        ck, D1, D2 = group_rows(g, poses)
    r = 3 if point else ck.shape[1]
    out = np.zeros((n, k, r, nc))

    def scatter(anchors, columns, values):
        """out[:, anchor, :, column] += values (n, P, r, c) for every pair's real columns, in one indexed add
        (anchor by anchor it cost more than the rows themselves); np.add.at where a target repeats (ties)."""
        columns = np.asarray(columns)
        real = columns < nc                   # padding columns carry zeros: dropped
        K = np.broadcast_to(np.asarray(anchors)[:, None], columns.shape)[real]
        C = columns[real]
        V = values.transpose(1, 3, 0, 2)[real]            # (pairs' real columns, n, r)
        if len(np.unique(K * (nc + 1) + C)) == len(K):
            out[:, K, :, C] += V
        else:
            np.add.at(out, (slice(None), K, slice(None), C), np.moveaxis(V, 0, 1))

    for side, (pk, cols, U) in enumerate(sides):
        if pk is None:
            continue
        if point:   # as in closure_state: E1 U = -R1^T (Uv + Uw x p2), E2 U = R1^T (Uv + Uw x p2)
            at = p2.reshape(n, k, 3)[:, pk, :, None]
            values = (1.0 if side else -1.0) * (R1t[:, pk] @ (U[:, :, :3] + cross(U[:, :, 3:], at, axis=2)))
        else:
            D, (Ra, pa) = (D1, D2)[side], poses[side]
            values = to_world(D, Ra, pa).reshape(n, k, r, 6)[:, pk] @ U
        scatter(pk, cols, values)
    for side, frame in enumerate(frames):
        if frame is None:
            continue
        cols, F = frame
        if point and side == 0:      # D1 = [-I, [cp]x]
            cp = np.einsum("nkij,nkj->nki", R1t, (p2 - p1).reshape(n, k, 3))
            # F (k, 6, f) gets a sample axis: cross works along the same axis 2 (the components) of both
            values = cross(np.broadcast_to(cp[..., None], (n, k, 3, F.shape[-1])), F[None, :, 3:], axis=2) - F[:, :3]
        elif point:                  # D2 = [R12, 0]
            values = (R1t @ R2.reshape(n, k, 3, 3)) @ F[:, :3]
        else:
            values = (D1, D2)[side].reshape(n, k, r, 6) @ F
        scatter(range(k), cols, values)
    return out.reshape(n, k * r, nc)
