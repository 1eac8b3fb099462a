#!/usr/bin/env python3
"""The fitted head's mouth measures against what they measure (README, "Accuracy").

W/d and H/d of the fit (width_fit, height_fit: the fitted model's landmarks) of three heads:
  ict         the default: the ICT head on the identity the processor fits of its own
              ([model] auto_identity_frames, no profile)
  mean-face   the ICT head on its mean face throughout (auto_identity_frames = 0)
  generated   the generated head of the test clips (build/models/default.lpm, F4)
each against
  - the truth of the generated talking-face clip (build/fixtures/talking_face_truth.csv: the
    rendered head's own W/d and H/d), over every frame;
  - the raw landmarks' width_2d and height_2d on the GRID clips (../shared/fixtures/grid_train,
    file-name order: the first 25 the tuning half, the other 25 and fixtures/grid the check
    half), per clip, then the median over the half's clips;
as min-max scaled RMSE and Pearson r (`lipdrive eval`'s definitions), and the closure metric of
height_fit on the GRID clips (`lipdrive eval --align`: bilabial words whose closure it shows).
Each agreement also from frame 20 on, once the ICT head's own identity is fitted (before it the
fit runs on the provisional identity of the first frame: docs/arkit.md).

usage: scripts/fit-grid.py [--build DIR] [--shared DIR]
"""
import argparse
import concurrent.futures
import csv
import json
import math
import pathlib
import statistics
import subprocess
import tempfile

from grid_halves import grid_halves

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("--build", default="build", type=pathlib.Path)
parser.add_argument("--shared", default=pathlib.Path(__file__).resolve().parents[1].parent / "shared",
                    type=pathlib.Path)
args = parser.parse_args()
lipdrive = args.build / "lipdrive"
work = pathlib.Path(tempfile.mkdtemp(prefix="fit-grid-"))
mean_face = work / "mean_face.toml"
mean_face.write_text(f'[model]\nfile = "{args.build / "models/ict_face_light.lpm"}"\nlandmark_set = "F5"\n'
                     "auto_identity_frames = 0\n")
IDENTITY_FRAMES = 20  # [model] auto_identity_frames, the default
HEADS = {"ict": [], "mean-face": ["--config", str(mean_face)],
         "generated": ["--model", str(args.build / "models/default.lpm"), "--landmark-set", "F4"]}


def column(rows, name):
    return [float(r[name]) if r.get(name) else math.nan for r in rows]


def agreement(truth, output):
    """(scaled RMSE, Pearson r) over the frames both have, each series min-max scaled."""
    pairs = [(t, o) for t, o in zip(truth, output) if not math.isnan(t) and not math.isnan(o)]
    t, o = [p[0] for p in pairs], [p[1] for p in pairs]
    def scaled(v):
        lo, hi = min(v), max(v)
        return [(x - lo) / (hi - lo) if hi > lo else 0.0 for x in v]
    rmse = math.sqrt(statistics.fmean((a - b) ** 2 for a, b in zip(scaled(t), scaled(o))))
    return rmse, statistics.correlation(t, o)


def after_identity(rows):
    """The rows from frame IDENTITY_FRAMES on: the ICT head's own identity is fitted by then."""
    return [r for r in rows if int(r["frame"]) >= IDENTITY_FRAMES]


def process(clip, head):
    out = work / f"{clip.stem}_{head}.csv"
    subprocess.run([lipdrive, "process", clip, "--out", out, *HEADS[head]], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return out


truth = list(csv.DictReader(open(args.build / "fixtures/talking_face_truth.csv")))
for head in HEADS:
    rows = list(csv.DictReader(open(process(args.build / "fixtures/talking_face.avi", head))))
    for frames, label in ((rows, ""), (after_identity(rows), f" from frame {IDENTITY_FRAMES}")):
        truth_rows = [truth[int(r["frame"])] for r in frames]
        figures = [f"{m}_fit {a[0]:.3f} / {a[1]:.3f}" for m in ("width", "height")
                   for a in [agreement(column(truth_rows, f"{m}_2d"), column(frames, f"{m}_fit"))]]
        print(f"talking face{label}, {head}: scaled RMSE / r against the truth: {', '.join(figures)}")

halves = grid_halves(args.shared / "fixtures")
for half, clips in halves.items():
    for head in HEADS:
        with concurrent.futures.ThreadPoolExecutor(2) as pool:
            tables = list(pool.map(lambda clip: process(clip, head), clips))
        per_clip = {"width": [], "height": []}
        after = {"width": [], "height": []}
        seen = words = 0
        for clip, table in zip(clips, tables):
            rows = list(csv.DictReader(open(table)))
            for m in per_clip:
                per_clip[m].append(agreement(column(rows, f"{m}_2d"), column(rows, f"{m}_fit")))
                later = after_identity(rows)
                after[m].append(agreement(column(later, f"{m}_2d"), column(later, f"{m}_fit")))
            closure = json.loads(subprocess.run(
                [lipdrive, "eval", "--pred", table, "--align", clip.with_suffix(".align"), "--columns", "height_fit",
                 "--json"], capture_output=True, text=True, check=True).stdout)["closure"][0]
            seen += closure["closures_seen"]
            words += closure["bilabial_words"]
        def medians(per):
            return ", ".join(f"{m}_fit {statistics.median(a[0] for a in v):.3f} / {statistics.median(a[1] for a in v):.3f}"
                             for m, v in per.items())
        print(f"GRID {half} ({len(clips)} clips), {head}: median scaled RMSE / r against the landmarks: "
              f"{medians(per_clip)}; height_fit closures {seen}/{words}; from frame {IDENTITY_FRAMES}: {medians(after)}")
