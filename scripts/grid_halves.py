"""The GRID split every evaluation script uses (docs/method.md 5): the 50 clips of
fixtures/grid_train in file-name order, the first 25 the tuning half (the only clips thresholds
were set on), the other 25 and the 2 of fixtures/grid the check half."""
import pathlib


def grid_halves(fixtures: pathlib.Path) -> dict:
    """{"tuning": [clip, ...], "check": [clip, ...]} of the .mpg clips under `fixtures`
    (../shared/fixtures); exits with a message when the clips are not there."""
    train = sorted((fixtures / "grid_train").glob("*.mpg"))
    if not train:
        raise SystemExit(f"{fixtures / 'grid_train'}: no GRID clips (../shared is needed for this script)")
    return {"tuning": train[:25], "check": train[25:] + sorted((fixtures / "grid").glob("*.mpg"))}
