#!/usr/bin/env python3
"""The ARKit weights of the ICT head on GRID speech (docs/arkit.md, "Figures").

Per clip (../shared/fixtures/grid_train/*.mpg in file-name order, then ../shared/fixtures/grid):
`lipdrive calibrate --input CLIP` fits the performer's identity on its first tracked frames (a
profile per clip), then `lipdrive process CLIP --config` fits every frame on it with the ICT
head and the jaw line (F5). With --mean-face the identity step is skipped (the mean face).

Reported, for the tuning half (the first 25 grid_train clips) and the check half (the other 25
and fixtures/grid) apart:
  jawOpen      Pearson r against the inner-lip height (height_2d) per clip over its tracked
               frames: median, mean, min, and pooled over all frames of the half
  closures     mouthClose and mouthPress (the mean of Left and Right) over the bilabial words
               (bin, blue, by, place, please, b, p, m; docs/method.md 5), each word's frames
               widened by 2 on each side: the mean weight there against the mean over the other
               speech words, and the share of bilabial words whose peak is above the 75th
               percentile of the clip's other speech frames
  rounding     mouthPucker and mouthFunnel the same way over "with", "two", "blue"
  rest         each ARKit weight over the final silence (from 3 frames after the start of the
               last 'sil' of the .align to its end, docs/method.md 5): the median per clip, then
               the median of those over the half's clips; printed for every weight above 0.01
  seal         the lips' seal (lip contact from the pixels) the same way over the bilabial, the
               rounded and the f/v words
  visemes      the viseme weights the ICT head's ARKit weights give (core/viseme_weights.hpp,
               docs/arkit.md "Visemes") the same way: B-M-P over the bilabial words (and the
               words where it reaches 0.5), Aah and BigAah over the words whose vowel is an open
               one (docs/method.md 7, class 10: AA AE AH AO AY), Ooh-Q and W over the rounded
               words (UW and a w onset), F-V over the words with f or v

usage: scripts/arkit-grid.py [--mean-face] [--build DIR] [--keep DIR]
"""
import argparse
import csv
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

from grid_halves import grid_halves

ROOT = pathlib.Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "fixtures"
BILABIAL = {"bin", "blue", "by", "place", "please", "b", "p", "m"}
ROUNDED = {"with", "two", "blue"}
# CMU pronunciations of GRID's words: open vowels (class 10), UW or a w onset, f or v.
OPEN_VOWEL = {"at", "by", "white", "five", "nine", "four", "one", "i", "y", "r"}
# close vowels (classes 12 and 14 without AW: IH IY UH UW), what the open ones are set against
CLOSE_VOWEL = {"bin", "in", "with", "six", "green", "three", "please", "b", "c", "d", "e", "g", "p", "t", "v", "z",
               "blue", "two", "soon", "q", "u"}
ROUNDED_SPEECH = {"with", "two", "blue", "soon", "q", "u", "one", "y"}
LABIODENTAL = {"five", "four", "f", "v", "seven"}
# (reported name, column(s) averaged, target words, what they are, the words they are set
# against: None = all other speech)
SERIES = [
    ("mouthClose", ["arkit_mouthClose"], BILABIAL, "bilabial", None),
    ("mouthPress", ["arkit_mouthPressLeft", "arkit_mouthPressRight"], BILABIAL, "bilabial", None),
    ("mouthPucker", ["arkit_mouthPucker"], ROUNDED, "with/two/blue", None),
    ("mouthFunnel", ["arkit_mouthFunnel"], ROUNDED, "with/two/blue", None),
    ("seal", ["seal"], BILABIAL, "bilabial", None),
    ("seal", ["seal"], ROUNDED_SPEECH, "rounded", None),
    ("seal", ["seal"], LABIODENTAL, "f/v", None),
    ("viseme B-M-P", ["viseme_B-M-P"], BILABIAL, "bilabial", None),
    ("viseme Aah", ["viseme_Aah"], OPEN_VOWEL, "open-vowel", None),
    ("viseme Aah", ["viseme_Aah"], OPEN_VOWEL, "open-vowel", CLOSE_VOWEL),
    ("viseme BigAah", ["viseme_BigAah"], OPEN_VOWEL, "open-vowel", CLOSE_VOWEL),
    ("viseme Ooh-Q", ["viseme_Ooh-Q"], ROUNDED_SPEECH, "rounded", None),
    ("viseme W", ["viseme_W"], ROUNDED_SPEECH, "rounded", None),
    ("viseme F-V", ["viseme_F-V"], LABIODENTAL, "f/v", None),
]


def pearson(x, y):
    mx, my = statistics.fmean(x), statistics.fmean(y)
    sxy = sum((a - mx) * (b - my) for a, b in zip(x, y))
    sxx = sum((a - mx) ** 2 for a in x)
    syy = sum((b - my) ** 2 for b in y)
    return sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else float("nan")


def quantile(values, p):  # the nearest rank, core/statistics.hpp
    ordered = sorted(values)
    return ordered[max(1, math.ceil(p * len(ordered))) - 1]


def words(align):
    """(first frame, last frame, word) of each word of a GRID .align (times / 1000 = frames)."""
    out = []
    for line in align.read_text().split("\n"):
        parts = line.split()
        if len(parts) == 3 and parts[2] not in ("sil", "sp"):
            out.append((int(parts[0]) // 1000, (int(parts[1]) - 1) // 1000, parts[2]))
    return out


def table(path):
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header = rows[0]
    columns = {name: [] for name in header if name != "source"}
    for row in rows[1:]:
        for name, value in zip(header, row):
            if name != "source":
                columns[name].append(float(value) if value != "" else float("nan"))
    return columns


def run(args, log):
    result = subprocess.run(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if result.returncode != 0:
        sys.exit(f"{' '.join(map(str, args))}: exit {result.returncode}\n{result.stderr}")
    log.write(result.stderr)


def process_clip(clip, work, build, mean_face, log):
    model = ROOT / "models" / "ict_face_light.lpm"
    config = work / f"config_{clip.stem}.toml"
    performer = "" if mean_face else clip.stem
    config.write_text(f'[model]\nfile = "{model}"\nlandmark_set = "F5"\n'
                      f'[performer]\nname = "{performer}"\nprofiles_dir = "{work}"\n')
    if not mean_face:
        calibrate = work / f"calibrate_{clip.stem}.toml"
        calibrate.write_text(config.read_text().replace(f'name = "{clip.stem}"', 'name = ""'))
        run([build / "lipdrive", "calibrate", "--config", calibrate, "--performer", clip.stem, "--input", clip,
             "--neutral-frames", "20"], log)
    out = work / f"table_{clip.stem}.csv"
    run([build / "lipdrive", "process", clip, "--config", config, "--out", out], log)
    return table(out)


def final_silence(align, n):
    """The frames of the final silence (docs/method.md 5: from 3 frames after its start to its end)."""
    last = [line.split() for line in align.read_text().split("\n") if len(line.split()) == 3][-1]
    if last[2] != "sil":
        return range(0)
    return range(int(last[0]) // 1000 + 3, min(n, (int(last[1]) - 1) // 1000 + 1))


def word_stats(clip_words, targets, weight, versus=None):
    """Per clip: (mean over target-word frames, mean over the other speech frames (those of the
    words in `versus` when given), words whose peak is above the 75th percentile of those frames,
    target words, words whose peak reaches 0.5)."""
    n = len(weight)
    target_frames, other_frames, peaks = set(), set(), []
    for first, last, word in clip_words:
        frames = range(max(0, first), min(n - 1, last) + 1)
        if word in targets:
            widened = [f for f in range(max(0, first - 2), min(n - 1, last + 2) + 1) if not math.isnan(weight[f])]
            target_frames.update(widened)
            peaks.append(max((weight[f] for f in widened), default=float("nan")))
        elif versus is None or word in versus:
            other_frames.update(f for f in frames if not math.isnan(weight[f]))
    other_frames -= target_frames
    if not peaks or not other_frames:
        return None
    others = [weight[f] for f in other_frames]
    bar = quantile(others, 0.75)
    return (statistics.fmean(weight[f] for f in target_frames), statistics.fmean(others),
            sum(p > bar for p in peaks), len(peaks), sum(p >= 0.5 for p in peaks))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mean-face", action="store_true", help="no identity per clip: the model's mean face")
    parser.add_argument("--build", type=pathlib.Path, default=ROOT / "build")
    parser.add_argument("--keep", type=pathlib.Path, help="keep the profiles and tables here")
    args = parser.parse_args()
    halves = grid_halves(SHARED)
    work = args.keep or pathlib.Path(tempfile.mkdtemp(prefix="arkit-grid-"))
    work.mkdir(parents=True, exist_ok=True)
    with open(work / "log.txt", "w") as log:
        for half, clips in halves.items():
            r, pooled_x, pooled_y = [], [], []
            sums = [[0.0, 0.0, 0, 0, 0, 0] for _ in SERIES]
            rest = {}  # ARKit column -> per-clip median over the final silence
            for clip in clips:
                c = process_clip(clip, work, args.build, args.mean_face, log)
                tracked = [i for i, t in enumerate(c["tracked"]) if t == 1]
                x = [c["height_2d"][i] for i in tracked]
                y = [c["arkit_jawOpen"][i] for i in tracked]
                r.append(pearson(x, y))
                pooled_x += x
                pooled_y += y
                clip_words = words(clip.with_suffix(".align"))
                silence = [f for f in final_silence(clip.with_suffix(".align"), len(c["tracked"])) if c["tracked"][f] == 1]
                if silence:
                    for column in (k for k in c if k.startswith("arkit_")):
                        rest.setdefault(column, []).append(statistics.median(c[column][f] for f in silence))
                for acc, (_, columns, targets, _, versus) in zip(sums, SERIES):
                    weight = [statistics.fmean(v) for v in zip(*(c[column] for column in columns))]
                    s = word_stats(clip_words, targets, weight, versus)
                    if s is None:
                        continue
                    for i, value in enumerate(s):
                        acc[i] += value
                    acc[5] += 1
            finite = [v for v in r if not math.isnan(v)]
            print(f"{half} ({len(clips)} clips): jawOpen r vs height_2d median {statistics.median(finite):.3f}, "
                  f"mean {statistics.fmean(finite):.3f}, min {min(finite):.3f}, pooled {pearson(pooled_x, pooled_y):.3f}")
            for (name, _, _, where, versus), (target, other, risen, total, reached, n) in zip(SERIES, sums):
                against = "other speech" if versus is None else "close-vowel words"
                print(f"  {name}: mean {target / n:.3f} over {where} words vs {other / n:.3f} over {against} "
                      f"({n} clips); peak above the clip's 75th percentile on {risen}/{total} words, "
                      f"at least 0.5 on {reached}/{total}")
            medians = {column[6:]: statistics.median(v) for column, v in rest.items()}
            print(f"  rest (final silence, median of {len(next(iter(rest.values())))} clip medians): "
                  f"mean over the 52 weights {statistics.fmean(medians.values()):.3f}; " +
                  ", ".join(f"{name} {m:.3f}" for name, m in sorted(medians.items(), key=lambda x: -x[1]) if m > 0.01))
    print(f"tables and profiles in {work}")


if __name__ == "__main__":
    main()
