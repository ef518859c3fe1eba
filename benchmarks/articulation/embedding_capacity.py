#!/usr/bin/env python3
# Can the default's embedding MLP represent the synthetic pixel features?
# Fits an MLP (a positional encoding of 6 octaves plus the input, W wide, L
# hidden ReLU layers, 16 outputs) directly to the feature function of
# `banmo synth` (docs/synth.md: e_k = sin(w_k . X + b_k), w_k ~ N(0, 2.5^2 I),
# normalised; numpy's own draws of the same distribution) by Adam on the
# mean cosine: 4,000 points of the quadruped's canonical box, 3,000 steps of
# 512 points. Prints the mean cosine reached on all points. Needs
# python3-numpy only; about a minute.
#
#   embedding_capacity.py [W L]   (default 16 1: problems/default.yaml's)
import sys

import numpy as np


def encode(x, octaves=6):
    out = [x]
    for k in range(octaves):
        out += [np.sin(2 ** k * np.pi * x), np.cos(2 ** k * np.pi * x)]
    return np.concatenate(out, 1)


def main():
    width, layers = (int(sys.argv[1]), int(sys.argv[2])) if len(sys.argv) > 2 else (16, 1)
    rng = np.random.default_rng(0)
    w, b = rng.normal(0, 2.5, (16, 3)), rng.uniform(0, 2 * np.pi, 16)
    x = rng.uniform([-1, -0.8, -0.35], [1, 0.6, 0.4], (4000, 3))
    target = np.sin(x @ w.T + b)
    target /= np.linalg.norm(target, axis=1, keepdims=True)
    p = encode(x)
    dims = [p.shape[1]] + [width] * layers + [16]
    ws = [rng.normal(0, np.sqrt(2 / dims[i]), (dims[i], dims[i + 1])) for i in range(len(dims) - 1)]
    bs = [np.zeros(d) for d in dims[1:]]
    params = ws + bs
    m1 = [np.zeros_like(q) for q in params]
    m2 = [np.zeros_like(q) for q in params]

    def forward(h):
        hs = [h]
        for i in range(len(ws)):
            z = h @ ws[i] + bs[i]
            h = np.maximum(z, 0) if i < len(ws) - 1 else z
            hs.append(h)
        return hs

    lr = 3e-3
    for step in range(3000):
        idx = rng.choice(len(x), 512)
        hs = forward(p[idx])
        n = np.linalg.norm(hs[-1], axis=1, keepdims=True) + 1e-9
        y = hs[-1] / n
        cos = (y * target[idx]).sum(1)
        g = -(target[idx] - y * cos[:, None]) / n / len(idx)  # d(-mean cos)/d output
        grads_w, grads_b = [None] * len(ws), [None] * len(ws)
        for i in reversed(range(len(ws))):
            grads_w[i], grads_b[i] = hs[i].T @ g, g.sum(0)
            if i > 0:
                g = (g @ ws[i].T) * (hs[i] > 0)
        for j, (q, d) in enumerate(zip(params, grads_w + grads_b)):
            m1[j] = 0.9 * m1[j] + 0.1 * d
            m2[j] = 0.999 * m2[j] + 0.001 * d * d
            q -= lr * (m1[j] / (1 - 0.9 ** (step + 1))) / (np.sqrt(m2[j] / (1 - 0.999 ** (step + 1))) + 1e-8)
    y = forward(p)[-1]
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    print(f'width {width}, {layers} hidden layer(s): mean cosine {(y * target).sum(1).mean():.3f}')


if __name__ == '__main__':
    main()
