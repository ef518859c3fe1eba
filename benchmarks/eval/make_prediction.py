#!/usr/bin/env python3
# Makes a dense "prediction" from a ground-truth PLY written by `banmo synth`
# (binary little endian, double x y z, uchar rgb, triangle faces), for the
# measurements of docs/eval.md ("Dense ground truth"). Standard library only.
#   python3 make_prediction.py GT.ply OUT.ply ROUNDS AMPLITUDE [NOISE] [still]
# Every triangle is split into n x n: n = 2^ROUNDS, or with ROUNDS = 0
# n = ceil(longest edge / (0.004 x bounding-box diagonal)) per triangle (an
# area-uniform vertex density, like marching cubes). Vertices then move by a
# smooth wave of AMPLITUDE x diagonal (x and y), Gaussian noise of NOISE x
# diagonal (default 0.002, seed 5), a rotation by 3 degrees about the z
# (viewing) axis through the box centre and a shift of 0.005 x diagonal;
# `still` keeps the surface exactly (no noise, no motion; AMPLITUDE 0 then
# gives the ceiling test's prediction).
import struct, sys, math, random
src, dst, rounds, amp = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
data = open(src, 'rb').read()
hdr_end = data.index(b'end_header\n') + len(b'end_header\n')
hdr = data[:hdr_end].decode().split('\n')
nv = int([l for l in hdr if l.startswith('element vertex')][0].split()[2])
nf = int([l for l in hdr if l.startswith('element face')][0].split()[2])
off = hdr_end; V = []
for i in range(nv):
    x, y, z = struct.unpack_from('<3d', data, off); off += 27; V.append((x, y, z))
F = []
for i in range(nf):
    c = data[off]; off += 1
    F.append(struct.unpack_from('<%di' % c, data, off)); off += 4 * c
lo = [min(v[k] for v in V) for k in range(3)]; hi = [max(v[k] for v in V) for k in range(3)]
diag = math.dist(lo, hi); cen = [(a + b) / 2 for a, b in zip(lo, hi)]
n0 = 2 ** rounds
out_v = []; out_f = []
for (a, b, c) in F:
    A, B, C = V[a], V[b], V[c]; base = len(out_v); idx = {}
    n = n0 if rounds > 0 else max(1, math.ceil(max(math.dist(A, B), math.dist(B, C), math.dist(C, A)) / (0.004 * diag)))
    for i in range(n + 1):
        for j in range(n + 1 - i):
            u, w = i / n, j / n
            idx[(i, j)] = len(out_v)
            out_v.append(tuple(A[k] + u * (B[k] - A[k]) + w * (C[k] - A[k]) for k in range(3)))
    for i in range(n):
        for j in range(n - i):
            out_f.append((idx[(i, j)], idx[(i + 1, j)], idx[(i, j + 1)]))
            if i + j + 1 < n: out_f.append((idx[(i + 1, j)], idx[(i + 1, j + 1)], idx[(i, j + 1)]))
random.seed(5); NOISE = float(sys.argv[5]) if len(sys.argv) > 5 else 0.002
STILL = len(sys.argv) > 6 and sys.argv[6] == 'still'
ang = 0.0 if STILL else math.radians(3.0); ca, sa = math.cos(ang), math.sin(ang)
res = []
for (x, y, z) in out_v:
    d = amp * diag * math.sin(4 * (x - cen[0]) / diag * 6.28) * math.cos(3 * (y - cen[1]) / diag * 6.28)
    x += d + (0 if STILL else random.gauss(0, NOISE * diag)); y += 0.5 * d + (0 if STILL else random.gauss(0, NOISE * diag)); z += (0 if STILL else random.gauss(0, NOISE * diag))
    # rotate about z through the centre, shift
    X, Y = x - cen[0], y - cen[1]
    res.append((cen[0] + ca * X - sa * Y + (0 if STILL else 0.005 * diag), cen[1] + sa * X + ca * Y, z))
with open(dst, 'wb') as f:
    f.write(('ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty double x\nproperty double y\nproperty double z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n' % (len(res), len(out_f))).encode())
    for v in res: f.write(struct.pack('<3d', *v))
    for t in out_f: f.write(struct.pack('<B3i', 3, *t))
print(len(res), 'vertices', len(out_f), 'faces')
