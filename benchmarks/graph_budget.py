#!/usr/bin/python3
"""graph_budget.py DATASET GRAPH MOSAICLOC [RUNS]: what bounds a self-built map's accuracy.

GRAPH is the pose graph `mosaicloc map poses --dataset DATASET --graph-out GRAPH` exported
(g2o, metres; one node per frame, world_from_camera; '# loop' before each loop closure's
edge). DATASET must have a ground truth (a simulated drive).

1. Every edge against the true relative pose of its two cameras, per kind (to the previous
   frame, to an earlier keyframe, loop closure): error RMS and mean, and the sigma the edge's
   information claims.
2. RUNS (default 8) graphs of the same edges and information whose measurements are the truth
   plus independent noise of each kind's measured RMS, each optimized by `mosaicloc map poses
   --graph-in` and compared with the truth after the best rigid alignment. Their spread is
   what links of that precision give on this drive's loops: if the real map's error lies in
   it, the links' own noise, not a bias or a wrong loop, is what bends the map.
"""
import bisect, json, math, os, random, re, statistics, subprocess, sys, tempfile

if len(sys.argv) not in (4, 5):
    sys.exit(__doc__)
dataset, graph_path, mosaicloc = sys.argv[1:4]
runs = int(sys.argv[4]) if len(sys.argv) == 5 else 8


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2])


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


yaml_path = os.path.join(dataset, "dataset.yaml")
found = re.search(r"vehicle_from_camera:\s*\{x_mm:\s*([-0-9.e+]+),\s*y_mm:\s*([-0-9.e+]+),\s*yaw_rad:\s*([-0-9.e+]+)\}",
                  open(yaml_path).read())
if not found:
    sys.exit(f"{yaml_path}: no vehicle_from_camera {{x_mm, y_mm, yaw_rad}}")
vehicle_from_camera = tuple(float(v) for v in found.groups())
stamps = [int(l.split(",")[0]) * 1e-9 for l in open(os.path.join(dataset, "cam0", "data.csv")) if l[0] != "#"]
rows = [l.split() for l in open(os.path.join(dataset, "groundtruth", "data.tum")) if l.strip() and l[0] != "#"]
if not rows:
    sys.exit(f"{dataset}: no ground truth")
truth_t = [float(r[0]) for r in rows]
truth_p = [(1000 * float(r[1]), 1000 * float(r[2]), 2 * math.atan2(float(r[6]), float(r[7]))) for r in rows]


def truth_at(t):  # world_from_vehicle, mm and rad, linearly interpolated
    k = min(max(bisect.bisect_left(truth_t, t), 1), len(truth_t) - 1)
    w = (t - truth_t[k - 1]) / (truth_t[k] - truth_t[k - 1])
    a, b = truth_p[k - 1], truth_p[k]
    return (a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * wrap(b[2] - a[2]))


cameras = [compose(truth_at(t), vehicle_from_camera) for t in stamps]

# The graph: its lines, and per edge (line index, from, to, kind, measurement in mm and rad).
lines = open(graph_path).readlines()
edges, vertices, loop_next = [], 0, False
for n, line in enumerate(lines, 1):
    f = line.split()
    if line.startswith("# loop"):
        loop_next = True
    elif f and f[0] == "VERTEX_SE2":
        vertices += 1
    elif f and f[0] == "EDGE_SE2":
        if len(f) != 12:
            sys.exit(f"{graph_path}:{n}: EDGE_SE2 needs 11 values")
        i, j = int(f[1]), int(f[2])
        kind = "loop" if loop_next else ("previous" if j == i + 1 else "keyframe")
        loop_next = False
        info = [float(v) for v in f[6:12]]  # upper triangle, metres
        edges.append((n - 1, i, j, kind, (1000 * float(f[3]), 1000 * float(f[4]), float(f[5])), info))
if vertices != len(cameras):
    sys.exit(f"{graph_path}: {vertices} nodes, but {dataset} has {len(cameras)} frames")


def claimed_sigma(info):  # sqrt of the covariance's diagonal, mm and rad
    a, b, c, d, e, f = info
    m = [[a, b, c], [b, d, e], [c, e, f]]
    det = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] ** 2) - m[0][1] * (m[0][1] * m[2][2] - m[1][2] * m[0][2]) +
           m[0][2] * (m[0][1] * m[1][2] - m[1][1] * m[0][2]))
    cov = [(m[1][1] * m[2][2] - m[1][2] ** 2) / det, (m[0][0] * m[2][2] - m[0][2] ** 2) / det,
           (m[0][0] * m[1][1] - m[0][1] ** 2) / det]
    return (1000 * math.sqrt(cov[0]), 1000 * math.sqrt(cov[1]), math.sqrt(cov[2]))


stats = {}
for _, i, j, kind, m, info in edges:
    true = compose(inverse(cameras[i]), cameras[j])
    error = (m[0] - true[0], m[1] - true[1], wrap(m[2] - true[2]))
    stats.setdefault(kind, []).append((error, claimed_sigma(info), math.hypot(true[0], true[1])))
print(f"edges of {graph_path} against the truth of {dataset}:")
print(f"{'kind':<9} {'count':>6} {'length mm':>9} | {'RMS x um':>8} {'y um':>6} {'yaw urad':>8} | "
      f"{'mean x um':>9} {'yaw urad':>8} | {'claimed x um':>12} {'yaw urad':>8}")
noise = {}
for kind in ("previous", "keyframe", "loop"):
    e = stats.get(kind, [])
    if not e:
        continue
    k = len(e)
    rms = [math.sqrt(sum(x[0][c] ** 2 for x in e) / k) for c in range(3)]
    mean = [sum(x[0][c] for x in e) / k for c in range(3)]
    claimed = [math.sqrt(sum(x[1][c] ** 2 for x in e) / k) for c in range(3)]
    noise[kind] = rms
    print(f"{kind:<9} {k:6d} {sum(x[2] for x in e) / k:9.1f} | {1000 * rms[0]:8.2f} {1000 * rms[1]:6.2f} "
          f"{1e6 * rms[2]:8.1f} | {1000 * mean[0]:+9.2f} {1e6 * mean[2]:+8.2f} | {1000 * claimed[0]:12.2f} "
          f"{1e6 * claimed[2]:8.1f}")


def solve(graph):
    result = subprocess.run([mosaicloc, "--quiet", "--json", "map", "poses", "--dataset", dataset, "--graph-in", graph],
                            capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"map poses --graph-in {graph}: {result.stderr.strip()}")
    error = json.loads(result.stdout)["vs_groundtruth"]
    return error["rms_mm"], error["max_mm"]


real = solve(graph_path)
print(f"\nthe graph as registered: {real[0]:.3f} mm RMS, {real[1]:.3f} mm max against the truth (aligned)")
rng = random.Random(1)
figures = []
with tempfile.TemporaryDirectory() as scratch:
    synthetic = os.path.join(scratch, "synthetic.g2o")
    for run in range(runs):
        out = list(lines)
        for n, i, j, kind, _, info in edges:
            true = compose(inverse(cameras[i]), cameras[j])
            s = noise[kind]
            m = (true[0] + rng.gauss(0, s[0]), true[1] + rng.gauss(0, s[1]), true[2] + rng.gauss(0, s[2]))
            out[n] = (f"EDGE_SE2 {i} {j} {m[0] / 1000:.15e} {m[1] / 1000:.15e} {m[2]:.15e} " +
                      " ".join(f"{v:.17g}" for v in info) + "\n")
        open(synthetic, "w").writelines(out)
        figures.append(solve(synthetic))
rms = sorted(f[0] for f in figures)
print(f"{runs} graphs with the measured noise, independent per edge: RMS median {statistics.median(rms):.3f} mm "
      f"(range {rms[0]:.3f} .. {rms[-1]:.3f}), max median {statistics.median(f[1] for f in figures):.3f} mm")
