#!/usr/bin/env python3
"""The lip closures of `open` on GRID under other cameras and lights (docs/method.md 9).

Each clip of ../shared/fixtures/grid_train (file-name order: the first 25 the tuning half, the
other 25 and fixtures/grid the check half) is re-encoded through an ffmpeg filter that stands
for another camera, lens or light (H.264, CRF 16, 4:2:0, the sound copied), then
`lipdrive process CLIP` and `lipdrive eval --align CLIP.align --columns open` score it with the
closure metric (docs/method.md 5): bilabial closures seen, and the clips that miss an opening
>= 0.5, a final-silence median <= 0.15 or its jitter <= 0.02, each with its figures. Nothing is
tuned here: the thresholds are those set on the tuning half at its own camera.

The `original` condition is the clips as recorded; `re-encoded` the same through the encoder
alone (what every other condition adds before its filter).

usage: scripts/grid-conditions.py [--build DIR] [--shared DIR] [--conditions NAME...] [--keep DIR]
"""
import argparse
import concurrent.futures
import json
import pathlib
import subprocess
import tempfile

from grid_halves import grid_halves

CONDITIONS = {
    "original": None,
    "re-encoded": "null",
    "rotated 15°": "rotate=15*PI/180:fillcolor=black",
    "rotated -20°": "rotate=-20*PI/180:fillcolor=black",
    "rotated 40°": "rotate=40*PI/180:fillcolor=black",
    # A head that rolls over the take, from upright to on its side: 30° a second, 90° at the
    # end of a 3-second clip, on a canvas large enough to keep the face in view.
    "rolling to 90°": "pad=576:460:(ow-iw)/2:(oh-ih)/2:gray,rotate=t*30*PI/180:fillcolor=gray",
    "mirrored": "hflip",
    "warm light (3000 K)": "colortemperature=temperature=3000",
    "cool light (9000 K)": "colortemperature=temperature=9000",
    "under-exposed": "eq=contrast=0.6:brightness=-0.15",
    "over-exposed": "eq=contrast=1.3:brightness=0.1",
    "dim and noisy": "eq=contrast=0.5:brightness=-0.2,noise=alls=8:allf=t",
    "sensor noise": "noise=alls=10:allf=t",
    "defocus (σ 1.5 px)": "gblur=sigma=1.5",
    "defocus (σ 3 px)": "gblur=sigma=3",
    "half size": "scale=iw/2:-2",
    "twice the size": "scale=iw*2:-2",
    "monochrome": "format=gray,format=yuv420p",
    # The face filling the picture, the chin at its bottom edge (cut when the mouth opens), as a
    # head-mounted camera framed close sees it.
    "framed close": "crop=150:170:80:85,scale=iw*4:-2",
    "30 frames/s": "fps=30",
    "60 frames/s": "fps=60",
    # Two fields a frame, from consecutive frames 40 ms apart, coded as interlaced video.
    "interlaced": ("tinterlace=mode=interleave_top,setfield=tff", ["-flags", "+ildct+ilme", "-x264-params", "tff=1"]),
}

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("--build", default="build", type=pathlib.Path)
parser.add_argument("--shared", default=pathlib.Path(__file__).resolve().parents[1].parent / "shared",
                    type=pathlib.Path)
parser.add_argument("--conditions", nargs="+", choices=list(CONDITIONS), default=list(CONDITIONS))
parser.add_argument("--keep", type=pathlib.Path, help="directory for the re-encoded clips and tables")
args = parser.parse_args()
lipdrive = args.build / "lipdrive"
work = args.keep or pathlib.Path(tempfile.mkdtemp(prefix="grid-conditions-"))

halves = grid_halves(args.shared / "fixtures")


def score(clip, name, condition):
    """The closure metric of one clip under one condition (lipdrive eval's JSON). A condition
    is an ffmpeg filter, or a filter and the encoder options it needs."""
    folder = work / name.replace(" ", "_").replace("/", "_")
    folder.mkdir(parents=True, exist_ok=True)
    source = clip
    if condition is not None:
        vf, encoding = condition if isinstance(condition, tuple) else (condition, [])
        source = folder / f"{clip.stem}.mp4"
        if not source.exists():
            subprocess.run(["ffmpeg", "-loglevel", "error", "-y", "-i", clip, "-vf", vf, "-c:v", "libx264", "-crf",
                            "16", "-pix_fmt", "yuv420p", *encoding, "-c:a", "copy", source], check=True)
    table = folder / f"{clip.stem}.csv"
    subprocess.run([lipdrive, "process", source, "--out", table], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    report = subprocess.run([lipdrive, "eval", "--pred", table, "--align", clip.with_suffix(".align"), "--columns",
                             "open", "--json"], capture_output=True, text=True, check=True).stdout
    return clip.stem, json.loads(report)["closure"][0]


def figure(value, decimals):
    return "untracked" if value is None else f"{value:.{decimals}f}"


def misses_a_target(closure):
    """Whether a clip's opening, final-silence median or jitter misses its bound; a figure
    without a tracked frame to take it from is null in the JSON, and a miss."""
    bounds = {"opening": lambda v: v >= 0.5, "silence_median": lambda v: v <= 0.15,
              "silence_jitter": lambda v: v <= 0.02}
    return any(closure[key] is None or not within(closure[key]) for key, within in bounds.items())


print("| condition | half | closures seen | clips missing opening / silence / jitter |")
print("|---|---|---|---|")
for name in args.conditions:
    for half, clips in halves.items():
        with concurrent.futures.ThreadPoolExecutor(2) as pool:
            results = list(pool.map(lambda clip: score(clip, name, CONDITIONS[name]), clips))
        seen = sum(c["closures_seen"] for _, c in results)
        words = sum(c["bilabial_words"] for _, c in results)
        missed = [f'{stem} "{w["word"]}"' for stem, c in results for w in c["words"] if not w["closed"]]
        failing = [f'{stem} ({figure(c["opening"], 2)}, {figure(c["silence_median"], 2)}, '
                   f'{figure(c["silence_jitter"], 3)})' for stem, c in results if misses_a_target(c)]
        print(f"| {name} | {half} | {seen}/{words}{' (' + ', '.join(missed) + ')' if missed else ''} | "
              f"{len(failing)}/{len(results)}{': ' + ', '.join(failing) if failing else ''} |", flush=True)
