"""Where the package's lines come from since a commit: `git blame` of every line of bev_mdo/*.py
split into lines unchanged since REV and lines written after it, by floor and by commit.

    python scripts/size_account.py [--since b65abe5] [--top 30]

b65abe5 is the tree the simplification targets were set on (18,295 lines, ros/ 4,722). The
commits in SIMPLIFICATION rewrote that house (one protocol, MDA classes, one typed config, the
evaluator split, the disciplines package, and the Python API the CLI was moved onto, which is a
feature too but is counted here to keep the account conservative); every other commit after REV
added a feature or a fix.
Lines of commits with fewer than --small lines each are counted apart and, to keep the account
conservative, with the simplification. Blame uses -w -M -C, so moved or copied lines keep their
first commit. Takes a few seconds.
"""
from __future__ import annotations

import argparse
import collections
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIMPLIFICATION = (
    "1ceca4b 56a80e9 c3068c6 2987446 9193b62 f243a23 f78d24d 4347721 2b66c5d b063605 0d7b8cb c9df1b0 "
    "4ec0269 e3b691d cb0cdad 1c8ce75 6733d49 546e8d1 b8c4b56 d37a6b8 a8740c8 82f0131 180ea1d 845ae76 "
    "21ae58c c06d3ac 953074b"
).split()


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout


def floor_of(path: str) -> str:
    parts = path.split("/")
    return "/".join(parts[:2]) if len(parts) > 2 else "bev_mdo (top level)"


def blame(path: str) -> list[str]:
    """The commit of each line of path (porcelain headers: 40 hex digits, then line numbers)."""
    commits = []
    for line in git("blame", "--line-porcelain", "-w", "-M", "-C", path).splitlines():
        head = line.split(" ", 1)[0]
        if len(head) == 40 and not line.startswith("\t") and all(c in "0123456789abcdef" for c in head):
            commits.append(head)
    return commits


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--since", default="b65abe5")
    ap.add_argument("--top", type=int, default=30)
    ap.add_argument("--small", type=int, default=15)
    args = ap.parse_args()
    before = set(git("rev-list", args.since).split())
    by_floor: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
    by_commit: collections.Counter[str] = collections.Counter()
    for path in sorted(git("ls-files", "bev_mdo").split()):
        if not path.endswith(".py"):
            continue
        for commit in blame(path):
            old = commit in before
            by_floor[floor_of(path)][0 if old else 1] += 1
            if not old:
                by_commit[commit] += 1
    unchanged = sum(v[0] for v in by_floor.values())
    written = sum(v[1] for v in by_floor.values())
    print(f"package {unchanged + written} lines: {unchanged} unchanged since {args.since}, {written} written since")
    print(f"{'floor':28s} {'unchanged':>9s} {'since':>6s}")
    for floor, (u, w) in sorted(by_floor.items(), key=lambda kv: -sum(kv[1])):
        print(f"{floor:28s} {u:9d} {w:6d}")
    house = sum(n for c, n in by_commit.items() if c[:7] in SIMPLIFICATION)
    small = sum(n for c, n in by_commit.items() if n < args.small and c[:7] not in SIMPLIFICATION)
    features = written - house - small
    print(f"written since: simplification commits {house}, commits of < {args.small} lines {small}, "
          f"features and fixes {features}")
    print(f"a package holding today's features and fixes needs at least {features} lines for them; "
          f"the house as found would have to fit in {18_300 - features} lines to stay under 18,300")
    print(f"\nthe {args.top} commits writing most lines since {args.since} (S: simplification)")
    for commit, n in by_commit.most_common(args.top):
        subject = git("log", "-1", "--format=%ad %s", "--date=format:%m-%d", commit).strip()
        tag = "S" if commit[:7] in SIMPLIFICATION else " "
        print(f"{n:5d} {tag} {commit[:7]} {subject[:100]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
