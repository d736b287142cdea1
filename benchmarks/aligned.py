#!/usr/bin/python3
"""aligned.py TUM GROUNDTRUTH_TUM [--placement]: prints "rms max" (mm) of the positions of TUM
after the best rigid alignment to the ground truth (interpolated at TUM's stamps); with
--placement also the alignment, as "rms max x_mm,y_mm,yaw_deg": TUM's frame in the truth's
(what `replay --truth-from-map` takes)."""
import bisect, math, sys
def read(path):
    rows = [l.split() for l in open(path) if l.strip() and not l.startswith("#")]
    return [float(r[0]) for r in rows], [(1000 * float(r[1]), 1000 * float(r[2])) for r in rows]
te, pe = read(sys.argv[1])
tt, pt = read(sys.argv[2])
pairs = []
for t, p in zip(te, pe):
    k = bisect.bisect_left(tt, t)
    if k == 0 or k == len(tt):
        continue
    w = (t - tt[k - 1]) / (tt[k] - tt[k - 1])
    q = tuple(pt[k - 1][i] + w * (pt[k][i] - pt[k - 1][i]) for i in range(2))
    pairs.append((p, q))
n = len(pairs)
mp = [sum(p[i] for p, _ in pairs) / n for i in range(2)]
mq = [sum(q[i] for _, q in pairs) / n for i in range(2)]
dot = cross = 0.0
for p, q in pairs:
    a, b = (p[0] - mp[0], p[1] - mp[1]), (q[0] - mq[0], q[1] - mq[1])
    dot += a[0] * b[0] + a[1] * b[1]
    cross += a[0] * b[1] - a[1] * b[0]
yaw = math.atan2(cross, dot)
c, s = math.cos(yaw), math.sin(yaw)
errors = []
for p, q in pairs:
    a = (p[0] - mp[0], p[1] - mp[1])
    errors.append(math.hypot(c * a[0] - s * a[1] + mq[0] - q[0], s * a[0] + c * a[1] + mq[1] - q[1]))
line = f"{math.sqrt(sum(e * e for e in errors) / n):.4f} {max(errors):.4f}"
if "--placement" in sys.argv[3:]:
    # truth = R (p - mp) + mq: the frame's origin at mq - R mp, turned by yaw.
    x, y = mq[0] - (c * mp[0] - s * mp[1]), mq[1] - (s * mp[0] + c * mp[1])
    line += f" {x:.6f},{y:.6f},{math.degrees(yaw):.9f}"
print(line)
