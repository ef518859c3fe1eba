#!/usr/bin/env python3
# Mask-and-flow articulation fit: per-frame bone transforms of a solve's
# canonical mesh and skinning weights fitted to the masks and the optical flow
# only (no ground truth), as a prototype of a motion estimate for the bone
# re-initialisation. benchmarks/articulation/README.md has the measurements.
# Needs python3-numpy, python3-scipy, python3-yaml and python3-opencv.
#
#   maskfit.py F DATA DST [--compare-oracle] [--init-from CK] [--w-... W]
#
# F is a folder with F/checkpoint (a banmo checkpoint, e.g. right after a
# bone re-initialisation), F/meshes (`banmo extract` of it: canonical.ply,
# skinning_weights.npy, frames/) and, for --compare-oracle only, F/eval
# (`banmo eval` of F/meshes/frames against DATA). DST gets the checkpoint with
# the fitted bone transforms (DST/checkpoint) and the posed meshes
# (DST/frames) for `banmo eval`.
#
# Per video, frame by frame (each frame starts from the previous one's fit,
# the first from the checkpoint's), Levenberg-Marquardt on the 6 B transform
# parameters of the frame (B bones: a turn about the rest bone centre and the
# centre's travel), the root pose fixed at the checkpoint's, in pixels:
#   outside:  the distance transform of the mask's background at each posed
#             vertex's projection (vertices must fall inside the mask);
#   cover:    each object pixel to the nearest projected vertex (the mask
#             must be covered), re-associated every iteration;
#   flow:     the previous frame's visible vertices, moved by the flow from
#             the previous frame, as targets (the motion between frames);
#   joints:   where two bones share skinning weight they move that part alike;
#   smooth:   the turn and travel change little from the previous frame
#             (a video's first frame: from the rest pose);
#   rest:     a pull to the rest pose (off by default);
#   match:    (--w-match > 0; off by default) object pixels to the fitted
#             vertex whose embedding is most similar to their feature, the
#             embedding being each vertex's mean pixel feature under the
#             checkpoint's motion (regressed directly, not the learnt one).
# --init-from CK starts every frame from CK's transforms instead (a
# diagnostic: where is the objective's minimum?); --compare-oracle prints,
# per bone, the fitted turn against oracle.py's (ground truth: F/eval and
# DATA's meshes).
import argparse, glob, os, sys, time

import cv2
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from oracle import POSE, Checkpoint, matrix_to_quat, procrustes, read_ply, write_ply  # noqa: E402


def skew(a):
    z = np.zeros(a.shape[:-1])
    return np.stack([np.stack([z, -a[..., 2], a[..., 1]], -1),
                     np.stack([a[..., 2], z, -a[..., 0]], -1),
                     np.stack([-a[..., 1], a[..., 0], z], -1)], -2)


def read_flow(path):
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit(f'{path}: cannot read the flow PNG')
    img = img[..., ::-1].astype(np.float64)  # BGR -> RGB
    return (img[..., :2] - 2 ** 15) / 64.0, img[..., 2] > 0


def read_mask(path):
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None or img.ndim != 2:
        sys.exit(f'{path}: cannot read the mask (8-bit grey PNG expected)')
    return img


def bilinear(img, u, v):
    """img at pixel-centre coordinates (u, v) (column i's centre is i + 0.5),
    with its gradient; clamped at the border."""
    h, w = img.shape
    x = np.clip(u - 0.5, 0, w - 1.001)
    y = np.clip(v - 0.5, 0, h - 1.001)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    a, b = img[y0, x0], img[y0, x0 + 1]
    c, d = img[y0 + 1, x0], img[y0 + 1, x0 + 1]
    val = (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * c + fx * d)
    gx = (1 - fy) * (b - a) + fy * (d - c)
    gy = (1 - fx) * (c - a) + fx * (d - b)
    return val, gx, gy


class Model(Checkpoint):
    """F/checkpoint and its extraction F/meshes."""

    def __init__(self, folder):
        Checkpoint.__init__(self, f'{folder}/checkpoint')
        self.centres = self.bone_centres
        self.x, self.colours, self.faces = read_ply(f'{folder}/meshes/canonical.ply')
        self.weights = np.load(f'{folder}/meshes/skinning_weights.npy').astype(np.float64)
        self.frame_paths = sorted(glob.glob(f'{folder}/meshes/frames/*.ply'))
        if len(self.frame_paths) != len(self.bones_t_offsets):
            sys.exit(f'{folder}: {len(self.frame_paths)} frame meshes for '
                     f'{len(self.bones_t_offsets)} frames in the checkpoint')

    def blend(self, js):
        return sum(self.weights[:, b:b + 1] * (self.x @ r.T + t) for b, (r, t) in enumerate(js))


class FrameFit:
    """Gauss-Newton on one frame's bone turns (R_b) and travels (tau_b):
    T_b x = R_b (x - c_b) + c_b + tau_b, y = sum_b w_b T_b x, root G."""

    def __init__(self, m, sub, pairs, intr, args):
        self.m, self.sub, self.pairs, self.intr, self.a = m, sub, pairs, intr, args
        self.xs = m.x[sub]
        self.ws = m.weights[sub]
        self.rel = self.xs[:, None, :] - m.centres[None]  # N x B x 3

    def pose(self, rs, taus, g):
        rot = np.einsum('bij,nbj->nbi', rs, self.rel)  # R_b (x - c_b)
        y = np.einsum('nb,nbi->ni', self.ws, rot + self.m.centres[None] + taus[None])
        cam = y @ g[0].T + g[1]
        fx, fy, cx, cy = self.intr
        uv = np.stack([fx * cam[:, 0] / cam[:, 2] + cx, fy * cam[:, 1] / cam[:, 2] + cy], -1)
        # d uv / d theta: P G_R [-w_b [R_b(x-c_b)]x, w_b I]
        z = cam[:, 2]
        p = np.zeros((len(cam), 2, 3))
        p[:, 0, 0], p[:, 0, 2] = fx / z, -fx * cam[:, 0] / z ** 2
        p[:, 1, 1], p[:, 1, 2] = fy / z, -fy * cam[:, 1] / z ** 2
        pg = p @ g[0]  # N x 2 x 3
        jw = -np.einsum('nij,nbjk->nbik', pg, skew(rot)) * self.ws[:, :, None, None]
        jt = pg[:, None] * self.ws[:, :, None, None]
        jac = np.concatenate([jw, jt], -1)  # N x B x 2 x 6
        jac = jac.transpose(0, 2, 1, 3).reshape(len(cam), 2, -1)
        return uv, jac, rot

    def fit(self, rs, taus, g, mask, targets, prev, matches=None):
        a, nb = self.a, self.m.num_bones
        fg = np.argwhere(mask == 255)[:, ::-1] + 0.5  # (u, v) of object pixels
        if len(fg) > a.cover_pixels:
            fg = fg[np.random.default_rng(0).choice(len(fg), a.cover_pixels, replace=False)]
        dt = ndimage.distance_transform_edt(mask != 255)
        dt = np.where(mask == 128, 0.0, dt)
        scale = self.intr[0] / g[1][2]  # pixels per model unit at the root
        lam, cost = 1e-3, float('nan')
        for _ in range(a.iterations):
            uv, jac, rot = self.pose(rs, taus, g)
            near = cKDTree(uv).query(fg)[1]

            def system(uv, jac, rot, rs, taus):
                rows, res = [], []
                n = len(uv)
                d, gx, gy = bilinear(dt, uv[:, 0], uv[:, 1])
                s = np.sqrt(a.w_outside / n)
                res.append(s * d)
                rows.append(s * (gx[:, None] * jac[:, 0] + gy[:, None] * jac[:, 1]))

                def points_to(idx, target, weight):
                    # Huber (a.huber px) by reweighting, per 2D residual.
                    s = np.sqrt(weight / max(len(idx), 1))
                    r = uv[idx] - target
                    nrm = np.linalg.norm(r, axis=1)
                    hw = s * np.sqrt(np.where(nrm < a.huber, 1.0, a.huber / np.maximum(nrm, 1e-9)))
                    res.append((hw[:, None] * r).ravel())
                    rows.append((hw[:, None, None] * jac[idx]).reshape(-1, jac.shape[2]))

                points_to(near, fg, a.w_cover)
                if targets is not None:
                    points_to(targets[0], targets[1], a.w_flow)
                if matches is not None:
                    points_to(matches[0], matches[1], a.w_match)
                # joints: T_b x - T_b' x at shared points (pixels via scale)
                np_ = sum(len(p[2]) for p in self.pairs)
                s = np.sqrt(a.w_joint / max(np_, 1)) * scale
                for b, c, pts in self.pairs:
                    db = (rot[pts, b] + self.m.centres[b] + taus[b]
                          - rot[pts, c] - self.m.centres[c] - taus[c])
                    jr = np.zeros((len(pts), 3, 6 * nb))
                    jr[:, :, 3 * b:3 * b + 3] = -skew(rot[pts, b])
                    jr[:, :, 3 * c:3 * c + 3] = skew(rot[pts, c])
                    jr[:, :, 3 * nb + 3 * b:3 * nb + 3 * b + 3] = np.eye(3)
                    jr[:, :, 3 * nb + 3 * c:3 * nb + 3 * c + 3] = -np.eye(3)
                    res.append((s * db).ravel())
                    rows.append(s * jr.reshape(-1, 6 * nb))
                # Smoothness to the previous frame (a video's first frame,
                # which has none, to the rest pose) and a pull to the rest.
                for ref, w in ((prev, a.w_smooth), (None, a.w_rest)):
                    if w == 0:
                        continue
                    for b in range(nb):
                        r0 = np.eye(3) if ref is None else ref[0][b]
                        t0 = np.zeros(3) if ref is None else ref[1][b]
                        om = Rotation.from_matrix(rs[b] @ r0.T).as_rotvec()
                        jr = np.zeros((6, 6 * nb))
                        jr[:3, 3 * b:3 * b + 3] = np.eye(3)
                        jr[3:, 3 * nb + 3 * b:3 * nb + 3 * b + 3] = np.eye(3) * scale
                        res.append(np.sqrt(w / nb) * np.concatenate([om * scale, (taus[b] - t0) * scale]))
                        jr[:3] *= scale
                        rows.append(np.sqrt(w / nb) * jr)
                return np.concatenate(res), np.concatenate(rows)

            # The projected-point jacobians are per bone [w, t]; permute them
            # to [w_0..w_B, t_0..t_B] like the joint and smoothness rows.
            perm = np.concatenate([np.arange(b * 6, b * 6 + 3) for b in range(nb)] +
                                  [np.arange(b * 6 + 3, b * 6 + 6) for b in range(nb)])
            jac = jac[:, :, perm]
            r, jm = system(uv, jac, rot, rs, taus)
            cost = r @ r
            h, gvec = jm.T @ jm, jm.T @ r
            for _ in range(8):
                step = -np.linalg.solve(h + lam * np.diag(np.diag(h) + 1e-9), gvec)
                nrs = np.stack([Rotation.from_rotvec(step[3 * b:3 * b + 3]).as_matrix() @ rs[b]
                                for b in range(nb)])
                ntaus = taus + step[3 * nb:].reshape(nb, 3)
                uv2, jac2, rot2 = self.pose(nrs, ntaus, g)
                r2, _ = system(uv2, jac2[:, :, perm], rot2, nrs, ntaus)
                if r2 @ r2 < cost:
                    rs, taus, lam = nrs, ntaus, max(lam / 3, 1e-6)
                    break
                lam *= 4
            else:
                break
        return rs, taus, cost


def mean_feature_embedding(m, sub, data_videos, tol):
    """Per fitted vertex, the normalised mean of the pixel features it is
    seen on (z-buffer, inside the mask) under the checkpoint's motion: an
    embedding regressed directly on the features, in place of the learnt
    one. Rows of vertices never seen are zero."""
    acc = np.zeros((len(sub), 16))
    k = 0
    for vi, video in enumerate(m.videos):
        fx, fy, cx, cy = video['intrinsics']
        for t in range(video['frames']):
            cam = read_ply(m.frame_paths[k])[0]
            feat = np.load(f'{data_videos[vi]}/features/{t:05d}.npy').astype(np.float64)
            mask = read_mask(f'{data_videos[vi]}/mask/{t:05d}.png') == 255
            h, w = mask.shape
            iu = np.floor(fx * cam[:, 0] / cam[:, 2] + cx).astype(int)
            iv = np.floor(fy * cam[:, 1] / cam[:, 2] + cy).astype(int)
            inside = (iu >= 0) & (iu < w) & (iv >= 0) & (iv < h)
            zbuf = np.full((h, w), np.inf)
            np.minimum.at(zbuf, (iv[inside], iu[inside]), cam[inside, 2])
            s = inside[sub]
            s[s] &= cam[sub[s], 2] <= zbuf[iv[sub[s]], iu[sub[s]]] + tol
            s[s] &= mask[iv[sub[s]], iu[sub[s]]]
            acc[s] += feat[iv[sub[s]], iu[sub[s]]]
            k += 1
    return acc / np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), 1e-12)


def feature_matches(psi, feat, mask, count, rng):
    """Up to `count` object pixels, each with the fitted vertex of the most
    similar embedding: (vertex indices into the subset, pixel centres)."""
    ys, xs = np.nonzero(mask == 255)
    if len(ys) > count:
        pick = rng.choice(len(ys), count, replace=False)
        ys, xs = ys[pick], xs[pick]
    f = feat[ys, xs].astype(np.float64)
    f /= np.linalg.norm(f, axis=1, keepdims=True) + 1e-12
    return (f @ psi.T).argmax(1), np.stack([xs + 0.5, ys + 0.5], -1)


def visible_targets(m, sub, js, g, intr, flow, valid, mask_next, tol):
    """The frame's visible fitted vertices (a z-buffer of all vertices) and
    their projections moved by the flow (where valid and inside the next
    mask)."""
    fx, fy, cx, cy = intr
    cam = m.blend(js) @ g[0].T + g[1]
    u = fx * cam[:, 0] / cam[:, 2] + cx
    v = fy * cam[:, 1] / cam[:, 2] + cy
    h, w = valid.shape
    iu, iv = np.floor(u).astype(int), np.floor(v).astype(int)
    inside = (iu >= 0) & (iu < w) & (iv >= 0) & (iv < h)
    zbuf = np.full((h, w), np.inf)
    np.minimum.at(zbuf, (iv[inside], iu[inside]), cam[inside, 2])
    s = sub[inside[sub]]
    vis = cam[s, 2] <= zbuf[iv[s], iu[s]] + tol
    s = s[vis]
    f = flow[iv[s], iu[s]]
    ok = valid[iv[s], iu[s]]
    tgt = np.stack([u[s], v[s]], -1) + f
    ti, tj = np.floor(tgt[:, 0]).astype(int), np.floor(tgt[:, 1]).astype(int)
    ok &= (ti >= 0) & (ti < w) & (tj >= 0) & (tj < h)
    ok[ok] &= mask_next[tj[ok], ti[ok]] == 255
    pos = {k: i for i, k in enumerate(sub)}
    return np.array([pos[k] for k in s[ok]], dtype=int), tgt[ok]


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument('folder')
    p.add_argument('data')
    p.add_argument('dst')
    p.add_argument('--vertices', type=int, default=3000, help='fitted vertices (a random subset)')
    p.add_argument('--cover-pixels', type=int, default=2000)
    p.add_argument('--iterations', type=int, default=20)
    p.add_argument('--w-outside', type=float, default=1.0)
    p.add_argument('--w-cover', type=float, default=1.0)
    p.add_argument('--w-flow', type=float, default=1.0)
    p.add_argument('--w-joint', type=float, default=1.0)
    p.add_argument('--w-smooth', type=float, default=0.01)
    p.add_argument('--w-rest', type=float, default=0.0)
    p.add_argument('--w-match', type=float, default=0.0,
                   help='feature matches against a mean-feature embedding (0 = off)')
    p.add_argument('--match-pixels', type=int, default=1000)
    p.add_argument('--huber', type=float, default=2.0, help='px')
    p.add_argument('--joint-weight', type=float, default=0.15,
                   help='a point joins bones b, c when both weights exceed this')
    p.add_argument('--visible-tol', type=float, default=0.05, help='z-buffer tolerance (model units)')
    p.add_argument('--init-from', help='checkpoint whose bone transforms start every frame (diagnostic)')
    p.add_argument('--compare-oracle', action='store_true')
    a = p.parse_args()
    m = Model(a.folder)
    rng = np.random.default_rng(0)
    sub = np.sort(rng.choice(len(m.x), min(a.vertices, len(m.x)), replace=False))
    ws = m.weights[sub]
    pairs = []
    for b in range(m.num_bones):
        for c in range(b + 1, m.num_bones):
            pts = np.where((ws[:, b] > a.joint_weight) & (ws[:, c] > a.joint_weight))[0]
            if len(pts):
                pairs.append((b, c, pts[:40]))
    print(f'{len(sub)} fitted vertices, {len(pairs)} bone pairs share skinning weight')
    # Diagnostic: every frame starts from another checkpoint's transforms
    # (e.g. the oracle's), to ask where the objective's minimum is.
    init = Checkpoint(a.init_from) if a.init_from else None
    if init is not None and init.bones_t_offsets != m.bones_t_offsets:
        sys.exit(f'{a.init_from}: not the layout of {a.folder}/checkpoint')
    data_videos = sorted(glob.glob(f'{a.data}/video_*'))
    if len(data_videos) != len(m.videos):
        sys.exit(f'{a.data}: {len(data_videos)} video_* folders, expected {len(m.videos)} (the checkpoint\'s videos)')
    psi = None
    if a.w_match > 0:
        psi = mean_feature_embedding(m, sub, data_videos, a.visible_tol)
    out_params = m.params.copy()
    frame_meshes = []
    k = 0
    t0 = time.time()
    fitted = {}
    for vi, video in enumerate(m.videos):
        intr = video['intrinsics']
        prev = None
        targets = None
        for t in range(video['frames']):
            js = m.transforms(k)
            posed = m.blend(js)
            g = procrustes(posed, read_ply(m.frame_paths[k])[0], np.ones(len(m.x)))
            mask = read_mask(f'{data_videos[vi]}/mask/{t:05d}.png')
            if init is not None:
                ji = init.transforms(k)
                rs = np.stack([r for r, _ in ji])
                taus = np.stack([r @ c + tt - c for (r, tt), c in zip(ji, m.centres)])
            elif prev is None:
                rs = np.stack([r for r, _ in js])
                taus = np.stack([r @ c + tt - c for (r, tt), c in zip(js, m.centres)])
            else:
                rs, taus = prev[0].copy(), prev[1].copy()
            fit = FrameFit(m, sub, pairs, intr, a)
            matches = None
            if psi is not None:
                feat = np.load(f'{data_videos[vi]}/features/{t:05d}.npy')
                matches = feature_matches(psi, feat, mask, a.match_pixels, np.random.default_rng(k))
            rs, taus, cost = fit.fit(rs, taus, g, mask, targets, prev, matches)
            prev = (rs, taus)
            fitted[k] = (rs, taus, g)
            jf = [(rs[b], m.centres[b] + taus[b] - rs[b] @ m.centres[b]) for b in range(m.num_bones)]
            bt = out_params[m.bones_t_offsets[k]:][:POSE * m.num_bones].reshape(-1, POSE)
            for b, (r, tt) in enumerate(jf):
                bt[b, :4], bt[b, 4:] = matrix_to_quat(r), tt
            frame_meshes.append(m.blend(jf) @ g[0].T + g[1])
            if t + 1 < video['frames']:
                flow, valid = read_flow(f'{data_videos[vi]}/flow/fw_1/{t:05d}.png')
                mask_next = read_mask(f'{data_videos[vi]}/mask/{t + 1:05d}.png')
                targets = visible_targets(m, sub, jf, g, intr, flow, valid, mask_next, a.visible_tol)
            ang = np.degrees([Rotation.from_matrix(r).magnitude() for r in rs])
            print(f'video {vi} frame {t:2d}: cost {cost:.3g}, bone turns mean {ang.mean():.1f} '
                  f'max {ang.max():.1f} deg, flow targets {len(targets[0]) if targets else 0} '
                  f'({time.time() - t0:.0f} s)', flush=True)
            k += 1
    os.makedirs(a.dst, exist_ok=True)
    frames = f'{a.dst}/frames'
    os.makedirs(frames, exist_ok=True)
    for path, v in zip(m.frame_paths, frame_meshes):
        write_ply(f'{frames}/{os.path.basename(path)}', v, m.colours, m.faces)
    m.write(f'{a.dst}/checkpoint', out_params)
    print(f'wrote {a.dst}/checkpoint and {len(frame_meshes)} meshes in {a.dst}/frames')
    if a.compare_oracle:
        from oracle import Solve
        s = Solve(a.folder, a.data, 1)
        err, ang_o, ang_e = [], [], []
        for k, (rs, taus, g) in fitted.items():
            for b, (rc, tc) in enumerate(s.lbs_fit(k)):
                ro = g[0].T @ rc
                err.append(Rotation.from_matrix(rs[b] @ ro.T).magnitude())
                ang_o.append(Rotation.from_matrix(ro).magnitude())
                ang_e.append(Rotation.from_matrix(rs[b]).magnitude())
        err, ang_o, ang_e = (np.degrees(np.reshape(e, (-1, m.num_bones))) for e in (err, ang_o, ang_e))
        order = np.argsort(m.centres[:, 1])
        for b in order:
            print(f'bone {b:2d} c=({m.centres[b, 0]:+.2f},{m.centres[b, 1]:+.2f},{m.centres[b, 2]:+.2f}) '
                  f'turn oracle {ang_o[:, b].mean():5.1f} fit {ang_e[:, b].mean():5.1f} '
                  f'error {err[:, b].mean():5.1f} deg (identity error {ang_o[:, b].mean():5.1f})')
        print(f'all bones: error {err.mean():.1f} deg against {ang_o.mean():.1f} at the identity')


if __name__ == '__main__':
    main()
