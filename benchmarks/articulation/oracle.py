#!/usr/bin/env python3
# Articulation oracle: how much of a finished synthetic solve's error is the
# per-frame bone transforms'? benchmarks/articulation/README.md has the
# measurements. Needs python3-numpy and python3-scipy (Debian packages).
#
#   oracle.py meshes OUT DATA DST [--mode lbs|rigid|static] [--corr-frames N]
#   oracle.py checkpoint OUT DATA DST [--corr-frames N] [--fraction F]
#
# OUT is a finished `banmo solve` output (OUT/checkpoint, OUT/meshes with
# canonical.ply, skinning_weights.npy and frames/, OUT/eval/per_frame.csv),
# DATA its synthetic dataset (ground-truth meshes of one rig: the same vertex
# ids in every frame). Each canonical vertex is given a ground-truth vertex:
# the nearest one to its posed position in the N frames of lowest CD (a vote
# over them when N > 1). Then per frame, in camera coordinates:
#   lbs:    per bone, the rigid transform of the canonical mesh onto the
#           ground-truth positions weighted by the bone's skinning weights
#           (weighted Procrustes), blended by the weights: the best per-frame
#           bone transforms of the learnt shape and weights, up to the blend;
#   rigid:  one rigid transform per frame (no articulation at all);
#   static: the learnt transforms kept, each bone's canonical part moved by
#           one rigid correction shared by all frames (shape, not motion).
# `meshes` writes the posed meshes (PLY, the names of OUT/meshes/frames) for
# `banmo eval --pred DST --gt DATA`; `checkpoint` writes OUT/checkpoint with
# the lbs transforms as its bone transforms J_b^t (model units, root frame:
# G^-1 times the camera-frame fit, G fitted from the learnt meshes) for
# `banmo render` or a resumed solve; --fraction F keeps F of each transform
# (F of its turn, about the rest bone centre, and F of the centre's travel).
import argparse, csv, glob, os, shutil, struct, sys

import numpy as np
import yaml
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

POSE = 7  # [qw, qx, qy, qz, tx, ty, tz]
VERTEX = np.dtype([('p', '<f8', 3), ('c', 'u1', 3)])
FACE = np.dtype([('n', 'u1'), ('i', '<i4', 3)])


def read_ply(path):
    """The meshes banmo writes: binary little endian, double xyz, uchar rgb."""
    data = open(path, 'rb').read()
    end = data.index(b'end_header\n') + len(b'end_header\n')
    header = data[:end].decode().split('\n')
    count = lambda what: int(next(l for l in header if l.startswith(what)).split()[2])
    nv, nf = count('element vertex'), count('element face')
    if 'property double x' not in header:
        sys.exit(f'{path}: expected double vertex coordinates (a banmo PLY)')
    v = np.frombuffer(data, VERTEX, nv, end)
    f = np.frombuffer(data, FACE, nf, end + nv * VERTEX.itemsize)
    return v['p'].copy(), v['c'].copy(), f['i'].copy()


def write_ply(path, vertices, colours, faces):
    v = np.zeros(len(vertices), VERTEX)
    v['p'], v['c'] = vertices, colours
    f = np.zeros(len(faces), FACE)
    f['n'], f['i'] = 3, faces
    header = ('ply\nformat binary_little_endian 1.0\nelement vertex %d\n'
              'property double x\nproperty double y\nproperty double z\n'
              'property uchar red\nproperty uchar green\nproperty uchar blue\n'
              'element face %d\nproperty list uchar int vertex_indices\nend_header\n'
              % (len(vertices), len(faces)))
    tmp = path + '.tmp'
    with open(tmp, 'wb') as out:
        out.write(header.encode() + v.tobytes() + f.tobytes())
    os.replace(tmp, path)


def procrustes(x, y, w):
    """R, t minimising sum_i w_i |R x_i + t - y_i|^2 (Kabsch, no reflection)."""
    w = w / w.sum()
    mx, my = w @ x, w @ y
    u, _, vt = np.linalg.svd(((x - mx) * w[:, None]).T @ (y - my))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, my - r @ mx


def quat_to_matrix(q):
    return Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()


def matrix_to_quat(r):
    x, y, z, w = Rotation.from_matrix(r).as_quat()
    return np.array([w, x, y, z])


class Checkpoint:
    """A banmo checkpoint's parameters (params.bin) and where its rest bones
    and per-frame bone transforms are in them."""

    def __init__(self, path):
        model = yaml.safe_load(open(f'{path}/model.yaml'))
        opts = model['options']
        if opts.get('delta_skinning', {}).get('enabled'):
            sys.exit(f'{path}: delta skinning is not supported (its pose codes change the layout)')
        self.path = path
        self.num_bones = opts['num_bones']
        self.videos = model['videos']
        self.frames_per_video = [v['frames'] for v in self.videos]
        raw = open(f'{path}/params.bin', 'rb').read()
        n = struct.unpack('<Q', raw[8:16])[0]
        self.raw, self.params = raw, np.frombuffer(raw[16:16 + 8 * n], '<f8').copy()
        # Per video: intrinsics (4), appearance code; per frame: root_delta,
        # root_init, bones_t (docs/solver.md, model.h).
        per_video = 4 + opts['field']['appearance_code_dim']
        per_frame = 2 * POSE + POSE * self.num_bones
        tail = sum(per_video + t * per_frame for t in self.frames_per_video)
        self.bones_t_offsets = []  # frame by frame, video-major
        o = len(self.params) - tail
        # Rest bones (10 each: centre, orientation, log scales) just before.
        self.bone_centres = self.params[o - 10 * self.num_bones:o].reshape(-1, 10)[:, :3].copy()
        for frames in self.frames_per_video:
            o += per_video
            for _ in range(frames):
                self.bones_t_offsets.append(o + 2 * POSE)
                o += per_frame

    def transforms(self, k):
        """Frame k's bone transforms J_b^t as (R, t) pairs."""
        bt = self.params[self.bones_t_offsets[k]:][:POSE * self.num_bones].reshape(-1, POSE)
        return [(quat_to_matrix(b[:4]), b[4:].copy()) for b in bt]

    def write(self, dst, params):
        """A copy of this checkpoint with these parameters, written through a
        temporary folder."""
        tmp = dst + '.tmp'
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.copytree(self.path, tmp)
        with open(f'{tmp}/params.bin', 'wb') as f:
            f.write(self.raw[:16] + params.astype('<f8').tobytes() + self.raw[16 + 8 * len(params):])
        shutil.rmtree(dst, ignore_errors=True)
        os.replace(tmp, dst)


class Solve(Checkpoint):
    """A finished solve, its dataset's ground truth and the correspondence."""

    def __init__(self, out, data, corr_frames):
        Checkpoint.__init__(self, f'{out}/checkpoint')
        self.x, self.colours, self.faces = read_ply(f'{out}/meshes/canonical.ply')
        self.weights = np.load(f'{out}/meshes/skinning_weights.npy').astype(np.float64)
        self.frame_paths = sorted(glob.glob(f'{out}/meshes/frames/*.ply'))
        gt = [p for v in sorted(glob.glob(f'{data}/video_*')) for p in sorted(glob.glob(f'{v}/gt_mesh/*.ply'))]
        if not (len(self.frame_paths) == len(gt) == len(self.bones_t_offsets)):
            sys.exit(f'{out}: {len(self.frame_paths)} frame meshes, {len(gt)} ground-truth meshes, '
                     f'{len(self.bones_t_offsets)} frames in the checkpoint: expected the same number')
        self.posed = [read_ply(p)[0] for p in self.frame_paths]
        self.gt = [read_ply(p)[0] for p in gt]
        if len({len(g) for g in self.gt}) != 1:
            sys.exit(f'{data}: the ground-truth meshes differ in vertex count (not one rig)')
        rows = list(csv.DictReader(open(f'{out}/eval/per_frame.csv')))
        best = np.argsort([float(r['chamfer_cm']) for r in rows])[:corr_frames]
        votes = np.stack([cKDTree(self.gt[t]).query(self.posed[t])[1] for t in best])
        self.match = np.array([np.bincount(c).argmax() for c in votes.T])
        print(f'correspondence from frames {list(best)} (lowest CD)')

    def learnt_transforms(self, k):
        """Frame k's bone transforms (root frame) and the fitted root G."""
        js = self.transforms(k)
        posed = sum(self.weights[:, b:b + 1] * (self.x @ r.T + t) for b, (r, t) in enumerate(js))
        g = procrustes(posed, self.posed[k], np.ones(len(self.x)))
        residual = np.abs(posed @ g[0].T + g[1] - self.posed[k]).max()
        if residual > 1e-5:
            sys.exit(f'frame {k}: the learnt transforms do not reproduce the written mesh '
                     f'({residual:.3g}); is the checkpoint the one the meshes came from?')
        return js, g

    def lbs_fit(self, k):
        target = self.gt[k][self.match]
        return [procrustes(self.x, target, self.weights[:, b] + 1e-12) for b in range(self.num_bones)]

    def blend(self, transforms, points=None):
        p = self.x if points is None else points
        return sum(self.weights[:, b:b + 1] * (p @ r.T + t) for b, (r, t) in enumerate(transforms))


def meshes(args):
    s = Solve(args.out, args.data, args.corr_frames)
    os.makedirs(args.dst, exist_ok=True)
    frames = range(len(s.frame_paths))
    if args.mode == 'static':
        cam = []
        for k in frames:
            js, (rg, tg) = s.learnt_transforms(k)
            cam.append([(rg @ r, rg @ t + tg) for r, t in js])
        corrections = []
        for b in range(s.num_bones):
            # |A (C x) - y| = |C x - A^-1 y| for rigid A: one Procrustes.
            src = np.concatenate([s.x] * len(cam))
            dst = np.concatenate([(s.gt[k][s.match] - cam[k][b][1]) @ cam[k][b][0] for k in frames])
            corrections.append(procrustes(src, dst, np.tile(s.weights[:, b], len(cam)) + 1e-12))
    for k in frames:
        if args.mode == 'lbs':
            v = s.blend(s.lbs_fit(k))
        elif args.mode == 'rigid':
            r, t = procrustes(s.x, s.gt[k][s.match], np.ones(len(s.x)))
            v = s.x @ r.T + t
        else:
            v = sum(s.weights[:, b:b + 1] * ((s.x @ rc.T + tc) @ ra.T + ta)
                    for b, ((rc, tc), (ra, ta)) in enumerate(zip(corrections, cam[k])))
        write_ply(os.path.join(args.dst, os.path.basename(s.frame_paths[k])), v, s.colours, s.faces)
    print(f'wrote {len(frames)} meshes ({args.mode}) to {args.dst}')


def checkpoint(args):
    s = Solve(args.out, args.data, args.corr_frames)
    params = s.params.copy()
    learnt, oracle = [], []
    for k in range(len(s.frame_paths)):
        js, (rg, tg) = s.learnt_transforms(k)
        # A view of params: writing bt writes the checkpoint's values.
        bt = params[s.bones_t_offsets[k]:][:POSE * s.num_bones].reshape(-1, POSE)
        for b, (rc, tc) in enumerate(s.lbs_fit(k)):
            r, t = rg.T @ rc, rg.T @ (tc - tg)  # J = G^-1 (camera-frame fit)
            if args.fraction != 1.0:
                # That fraction of the turn, about the rest centre c, which
                # moves that fraction of the way to J c.
                c = s.bone_centres[b]
                r = Rotation.from_rotvec(args.fraction * Rotation.from_matrix(r).as_rotvec()).as_matrix()
                t = c + args.fraction * (rg.T @ (rc @ c + tc - tg) - c) - r @ c
            bt[b, :4], bt[b, 4:] = matrix_to_quat(r), t
            learnt.append(Rotation.from_matrix(js[b][0]).magnitude())
            oracle.append(Rotation.from_matrix(r).magnitude())
    s.write(args.dst, params)
    print(f'wrote {args.dst}: bone rotation mean {np.degrees(np.mean(learnt)):.1f} deg learnt, '
          f'{np.degrees(np.mean(oracle)):.1f} deg oracle')


def main():
    p = argparse.ArgumentParser(description=__doc__)
    sub = p.add_subparsers(dest='command', required=True)
    for name in ('meshes', 'checkpoint'):
        q = sub.add_parser(name)
        q.add_argument('out', help='finished banmo solve output folder')
        q.add_argument('data', help='its synthetic dataset folder')
        q.add_argument('dst', help='output folder')
        q.add_argument('--corr-frames', type=int, default=1,
                       help='frames of lowest CD that vote for the correspondence')
        if name == 'meshes':
            q.add_argument('--mode', choices=('lbs', 'rigid', 'static'), default='lbs')
        else:
            q.add_argument('--fraction', type=float, default=1.0,
                           help='that fraction of each oracle transform (turn and centre travel '
                                'about the rest bone centre; 1 = all of it)')
    args = p.parse_args()
    meshes(args) if args.command == 'meshes' else checkpoint(args)


if __name__ == '__main__':
    main()
