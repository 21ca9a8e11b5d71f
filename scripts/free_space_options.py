"""Two ways to keep observed-free space, measured before choosing one (issue 29, item 3).

Sweeps 0 and 2 of ouster_os1.conf are mapped at BYTES (the map's surface is what is occupied,
within 10 cm); their rays mark what was seen free, kept either as
- a voxel grid of the voxels each ray passes through up to one voxel before its end, coded as
  an octree bitstream (2 bits a child: unknown, observed, mixed), or
- range images as NanoMap keeps them: per sweep, the least range of its returns in each pixel
  of an elevation x azimuth grid from its origin, 8 bits on a log scale.
On 20,000 of sweep 1's held-out rays, the states of four points before each end (should be
free, never occupied) and of the point 2 m behind it where no training ray passed within
0.1 m (should be unknown).

Usage: python scripts/free_space_options.py [BYTES]   (the mema package and numpy; data from
../shared/data or MEMA_DATA). Takes a few minutes.
"""
import os, sys, tempfile
import numpy as np
import mema

data = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data")
data = os.environ.get("MEMA_DATA", data)
nbytes = int(sys.argv[1]) if len(sys.argv) > 1 else 9600
conf = [l.split() for l in open(os.path.join(data, "ouster_os1.conf")) if l.startswith("bmesh")]
tmp = tempfile.mkdtemp()
def write_conf(name, rows):
    p = os.path.join(tmp, name)
    with open(p, "w") as f:
        for r in rows:
            f.write(" ".join(["bmesh", os.path.join(data, r[1])] + r[2:]) + "\n")
    return p
train = mema.read_cloud(write_conf("train.conf", [conf[0], conf[2]]))
held = mema.read_cloud(write_conf("held.conf", [conf[1]]))
m = mema.map(train, bytes=nbytes)

def rays(cloud):
    origins, ends = cloud.sensors
    pts = np.asarray(cloud)
    o = np.repeat(np.asarray(origins), np.diff(np.r_[0, np.asarray(ends)]), axis=0)
    d = pts - o
    r = np.linalg.norm(d, axis=1)
    return o, d / r[:, None], r

to, tu, tr = rays(train)
ho, hu, hr = rays(held)
lo = np.minimum(to.min(0), (to + tu * tr[:, None]).min(0)) - 1.0

def observed(voxel, margin=1.0):
    """Voxel keys every training ray passes through (sampled at voxel/2 steps) or ends in."""
    keys = []
    for i in range(0, len(tr), 20000):
        o, u, r = to[i:i + 20000], tu[i:i + 20000], tr[i:i + 20000]
        steps = np.arange(0, r.max() + voxel, voxel / 2)
        for s0 in range(0, len(steps), 64):
            t = steps[s0:s0 + 64][None, :]
            ok = t <= r[:, None] - margin * voxel
            p = o[:, None, :] + t[..., None] * u[:, None, :]
            k = np.floor((p[ok] - lo) / voxel).astype(np.int64)
            keys.append(np.unique(k, axis=0))
    return np.unique(np.concatenate(keys), axis=0)

def octree_bytes(keys):
    """An octree over the observed voxels: 2 bits a child of every mixed node (unknown,
    observed, mixed), as OctoMap's binary stream codes free/occupied/inner; full subtrees
    collapse into one 'observed' child."""
    depth = int(np.ceil(np.log2(keys.max() + 1)))
    level = {tuple(k) for k in keys}
    full = level  # sets of voxel keys at each level whose subtree is fully observed
    mixed_nodes = 0
    cur_full, cur_any = set(map(tuple, keys)), set(map(tuple, keys))
    for d in range(depth):
        parents_any, parents_children_full = {}, {}
        for k in cur_any:
            pk = (k[0] >> 1, k[1] >> 1, k[2] >> 1)
            parents_any[pk] = parents_any.get(pk, 0) + 1
            if k in cur_full:
                parents_children_full[pk] = parents_children_full.get(pk, 0) + 1
        new_full = {pk for pk, n in parents_children_full.items() if n == 8}
        mixed_nodes += len(parents_any) - len(new_full)
        cur_full, cur_any = new_full, set(parents_any)
    return mixed_nodes * 2  # 8 children x 2 bits = 2 bytes a mixed node

def state(points, voxel, keyset, tol=0.1):
    d, _ = m.nearest(points)
    occ = np.abs(d) <= tol
    k = np.floor((points - lo) / voxel).astype(np.int64)
    obs = np.array([tuple(x) in keyset for x in k])
    return np.where(occ, 2, np.where(obs, 1, 0))  # 0 unknown, 1 free, 2 occupied

rng = np.random.default_rng(0)
pick = rng.choice(len(hr), 20000, replace=False)
before = np.concatenate([ho[pick] + (f * hr[pick])[:, None] * hu[pick] for f in (0.2, 0.4, 0.6, 0.8)])
behind = ho[pick] + (hr[pick] + 2.0)[:, None] * hu[pick]
# Behind-the-wall truth at 0.1 m: did any training ray pass within a 0.1 m voxel of the point?
fine = {tuple(k) for k in observed(0.1, 0.0)}
kb = np.floor((behind - lo) / 0.1).astype(np.int64)
unseen = ~np.array([tuple(x) in fine for x in kb])
print(f"map {nbytes} bytes; behind-endpoint samples no training ray passed (0.1 m): {unseen.mean():.3f}")
print("| voxel | observed voxels | octree bytes | before end: occupied | free | unknown | behind, unseen: unknown |")
print("|---|---|---|---|---|---|---|")
for voxel in (0.5, 1.0, 2.0):
    keys = observed(voxel)
    ks = {tuple(k) for k in keys}
    b = octree_bytes(keys)
    sb = state(before, voxel, ks)
    sh = state(behind[unseen], voxel, ks)
    print(f"| {voxel} m | {len(keys):,} | {b:,} | {np.mean(sb == 2):.3f} | {np.mean(sb == 1):.3f} | "
          f"{np.mean(sb == 0):.3f} | {np.mean(sh == 0):.3f} |")

# Range images as NanoMap keeps them: per sweep, the least range of its returns in each pixel of
# an elevation x azimuth grid from the sweep's origin, 8 bits on a log scale (rounded down, so
# free is never claimed past a return). A point is free if a sweep's image puts it at least
# `margin` nearer than the pixel's least range; unknown behind it.
origins, ends = train.sensors
starts = np.r_[0, np.asarray(ends)[:-1]]
P = np.asarray(train)
def sph(p, o):
    d = p - o
    r = np.linalg.norm(d, axis=1)
    return np.arctan2(d[:, 1], d[:, 0]), np.arcsin(np.clip(d[:, 2] / np.maximum(r, 1e-9), -1, 1)), r
R0, R1 = 0.3, 120.0
def enc(r):
    return np.clip(np.floor(255 * np.log(np.maximum(r, R0) / R0) / np.log(R1 / R0)), 0, 255)
def dec(q):
    return R0 * np.exp(q / 255 * np.log(R1 / R0))
def images(h, w):
    out = []
    for o, s, e in zip(np.asarray(origins), starts, np.asarray(ends)):
        az, el, r = sph(P[s:e], o)
        lo_el, hi_el = el.min(), el.max()
        i = np.clip(((el - lo_el) / (hi_el - lo_el) * h).astype(int), 0, h - 1)
        j = np.clip(((az + np.pi) / (2 * np.pi) * w).astype(int), 0, w - 1)
        img = np.full(h * w, 256.0)  # no return in the pixel: nothing known
        np.minimum.at(img, i * w + j, enc(r))
        out.append((o, lo_el, hi_el, img))
    return out
def free_by_images(points, imgs, h, w, margin=0.2):
    free = np.zeros(len(points), bool)
    for o, lo_el, hi_el, img in imgs:
        az, el, r = sph(points, o)
        inside = (el >= lo_el) & (el <= hi_el)
        i = np.clip(((el - lo_el) / (hi_el - lo_el) * h).astype(int), 0, h - 1)
        j = np.clip(((az + np.pi) / (2 * np.pi) * w).astype(int), 0, w - 1)
        q = img[i * w + j]
        free |= inside & (q < 256) & (r < dec(q) - margin)
    return free
print()
print("| range image | bytes (2 sweeps) | before end: occupied | free | unknown | behind, unseen: unknown |")
print("|---|---|---|---|---|---|")
for h, w in ((8, 64), (16, 128), (32, 256)):
    imgs = images(h, w)
    def st(points):
        d, _ = m.nearest(points)
        occ = np.abs(d) <= 0.1
        return np.where(occ, 2, np.where(free_by_images(points, imgs, h, w), 1, 0))
    sb, sh = st(before), st(behind[unseen])
    print(f"| {h} x {w} | {2 * h * w:,} | {np.mean(sb == 2):.3f} | {np.mean(sb == 1):.3f} | "
          f"{np.mean(sb == 0):.3f} | {np.mean(sh == 0):.3f} |")
