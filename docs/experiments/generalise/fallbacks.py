#!/usr/bin/env python3
"""Where active inference lost the line in an experiment's evaluation runs.

For every evaluation run folder under DIR (`mta experiment --out DIR`), reads trace.csv (every
5th step: x, y, source) and the run's track (written with `mta track --seed N`), and prints, per
fallback onset (a step where the source turns to `fallback`), the curvature of the line at the
car's nearest point and the tightest curvature within 0.3 m before it, against the track's own
curvature quantiles. Curvature as in `mta analyze`: the circle through the line's points 10 cm
either side (signed, left turns positive).

usage: fallbacks.py DIR [MTA]   (MTA: the mta binary, default target/release/mta)
"""
import csv, math, os, subprocess, sys, tempfile

def load_track(spec, mta):
    path = spec
    if spec.startswith("generated:"):
        path = os.path.join(tempfile.gettempdir(), spec.replace(":", "-") + ".csv")
        subprocess.run([mta, "track", "--seed", spec.split(":")[1], "--out", path],
                       check=True, capture_output=True)
    pts = []
    for line in open(path):
        if line[0] in "#x":
            continue
        x, y = line.split(",")[:2]
        pts.append((float(x), float(y)))
    return pts

class Line:
    def __init__(self, pts):
        self.pts, self.cum = pts, [0.0]
        for i in range(len(pts)):
            self.cum.append(self.cum[-1] + math.dist(pts[i], pts[(i + 1) % len(pts)]))
        self.length = self.cum[-1]

    def at(self, s):
        s %= self.length
        for i in range(len(self.pts)):
            if self.cum[i + 1] >= s:
                a, b = self.pts[i], self.pts[(i + 1) % len(self.pts)]
                t = (s - self.cum[i]) / max(self.cum[i + 1] - self.cum[i], 1e-12)
                return (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))

    def curvature(self, s, h=0.1):
        a, b, c = self.at(s - h), self.at(s), self.at(s + h)
        cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        sides = math.dist(a, b) * math.dist(b, c) * math.dist(a, c)
        return 2 * cross / sides if sides > 0 else 0.0

    def nearest_s(self, q):
        best = (float("inf"), 0.0)
        n = int(self.length / 0.005)
        for k in range(n):
            s = k * 0.005
            d = math.dist(self.at(s), q)
            if d < best[0]:
                best = (d, s)
        return best[1]

def main():
    root = sys.argv[1]
    mta = sys.argv[2] if len(sys.argv) > 2 else "target/release/mta"
    lines = {}
    for dirpath, _, files in sorted(os.walk(root)):
        name = os.path.basename(dirpath)
        if "trace.csv" not in files or not name.startswith("eval-"):
            continue
        track = name[len("eval-"):].replace("generated-", "generated:", 1)
        if track not in lines:
            lines[track] = Line(load_track(track, mta))
        line = lines[track]
        rows = list(csv.DictReader(open(os.path.join(dirpath, "trace.csv"))))
        onsets = [r for p, r in zip(rows, rows[1:])
                  if r["source"] == "fallback" and p["source"] != "fallback"]
        if not onsets:
            continue
        ks = sorted(abs(line.curvature(i * 0.01)) for i in range(int(line.length / 0.01)))
        q = lambda f: ks[int(f * (len(ks) - 1))]
        print(f"{os.path.relpath(dirpath, root)}: {len(onsets)} fallback(s); track |curvature| "
              f"median {q(0.5):.2f}, 90% {q(0.9):.2f}, max {ks[-1]:.2f} 1/m")
        for r in onsets:
            s = line.nearest_s((float(r["x"]), float(r["y"])))
            here = line.curvature(s)
            before = max((line.curvature(s - d * 0.01) for d in range(31)), key=abs)
            print(f"  step {r['step']:>5} at ({float(r['x']):+.2f}, {float(r['y']):+.2f}) s {s:.2f} m: "
                  f"curvature {here:+.2f}, tightest in the 0.3 m before {before:+.2f} 1/m")

main()
