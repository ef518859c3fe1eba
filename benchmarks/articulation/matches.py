#!/usr/bin/env python3
# How sharp are the feature matches, and which motion do they agree with?
# benchmarks/articulation/README.md has the measurements. Needs
# python3-numpy, python3-scipy, python3-yaml and python3-opencv.
#
#   matches.py F DATA [OTHER_CHECKPOINT ...] [--mean-features]
#
# F as for maskfit.py (F/checkpoint and its `banmo extract` in F/meshes,
# with embedding.npy). Every object pixel of every frame of DATA is matched
# to the canonical vertex whose embedding is most similar to the pixel's
# feature (cosine, hard argmax over all vertices: no grid, no softmax).
# Printed: the mean best cosine, and the median distance (px) between each
# pixel and its matched vertex posed and projected with F's bone transforms
# and with each OTHER_CHECKPOINT's (same layout, e.g. `oracle.py
# checkpoint`), over all pixels and over the pixels matched to leg vertices
# (dominant bone centred below canonical y = -0.15). --mean-features: the
# embedding is each vertex's mean pixel feature under F's motion
# (maskfit.py's mean_feature_embedding) instead of embedding.npy.
import glob, os, sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from maskfit import Model, mean_feature_embedding  # noqa: E402
from oracle import Checkpoint, procrustes, read_ply  # noqa: E402


def main():
    args = [x for x in sys.argv[1:] if x != '--mean-features']
    if len(args) < 2 or args[0] in ('-h', '--help'):
        sys.exit('usage: matches.py F DATA [OTHER_CHECKPOINT ...] [--mean-features] '
                 '(see the comment at its top)')
    folder, data = args[0], args[1]
    m = Model(folder)
    motions = [('learnt', m)]
    for path in args[2:]:
        c = Checkpoint(path)
        if c.bones_t_offsets != m.bones_t_offsets:
            sys.exit(f'{path}: not the layout of {folder}/checkpoint')
        motions.append((path, c))
    videos = sorted(glob.glob(f'{data}/video_*'))
    if len(videos) != len(m.videos):
        sys.exit(f'{data}: {len(videos)} video_* folders, expected {len(m.videos)} (the checkpoint\'s videos)')
    if '--mean-features' in sys.argv:
        psi = mean_feature_embedding(m, np.arange(len(m.x)), videos, tol=0.05)
    else:
        psi = np.load(f'{folder}/meshes/embedding.npy').astype(np.float64)
        psi /= np.linalg.norm(psi, axis=1, keepdims=True) + 1e-12
    leg_vertex = (m.centres[:, 1] < -0.15)[m.weights.argmax(1)]
    cosines, err, err_legs = [], {n: [] for n, _ in motions}, {n: [] for n, _ in motions}
    k = 0
    for vi, video in enumerate(m.videos):
        fx, fy, cx, cy = video['intrinsics']
        for t in range(video['frames']):
            feat = np.load(f'{videos[vi]}/features/{t:05d}.npy').astype(np.float64)
            mask = cv2.imread(f'{videos[vi]}/mask/{t:05d}.png', cv2.IMREAD_UNCHANGED) == 255
            ys, xs = np.nonzero(mask)
            f = feat[ys, xs]
            f /= np.linalg.norm(f, axis=1, keepdims=True) + 1e-12
            sim = f @ psi.T
            best = sim.argmax(1)
            cosines.append(sim.max(1).mean())
            pixels = np.stack([xs + 0.5, ys + 0.5], -1)
            g = procrustes(m.blend(m.transforms(k)), read_ply(m.frame_paths[k])[0], np.ones(len(m.x)))
            for name, c in motions:
                p = m.blend(c.transforms(k)) @ g[0].T + g[1]
                uv = np.stack([fx * p[:, 0] / p[:, 2] + cx, fy * p[:, 1] / p[:, 2] + cy], -1)
                e = np.linalg.norm(uv[best] - pixels, axis=1)
                err[name].append(np.median(e))
                legs = leg_vertex[best]
                err_legs[name].append(np.median(e[legs]) if legs.any() else np.nan)
            k += 1
    print(f'{k} frames: mean best cosine {np.mean(cosines):.3f}')
    for name, _ in motions:
        print(f'{name}: matched vertex to pixel, median {np.mean(err[name]):.2f} px '
              f'(leg vertices {np.nanmean(err_legs[name]):.2f} px), mean over frames')


if __name__ == '__main__':
    main()
