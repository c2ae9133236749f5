"""Size of the package: lines of bev_mdo/ros/ and of each package, the largest modules and the
longest functions (ast), for a checkout given by --root (default: this one). Compare trees before and
after a change with it.

    python bench/code_size.py [--root DIR] [--json bench/results/code_size.json] [--top 10]
"""
from __future__ import annotations

import argparse
import ast
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def measure(root: Path, top: int = 10) -> dict:
    pkg = root / "bev_mdo"
    modules = {str(p.relative_to(root)): len(p.read_text().splitlines()) for p in sorted(pkg.rglob("*.py"))}
    packages: dict[str, int] = {}
    for path, n in modules.items():
        parts = Path(path).parts
        key = "/".join(parts[:2]) if len(parts) > 2 else parts[0] + "/(top level)"
        packages[key] = packages.get(key, 0) + n
    functions = []
    for path in modules:
        tree = ast.parse((root / path).read_text())
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.append({"function": f"{path}:{node.name}", "lines": node.end_lineno - node.lineno + 1})
    functions.sort(key=lambda f: -f["lines"])
    return {
        "ros_lines": packages.get("bev_mdo/ros", 0),
        "packages": dict(sorted(packages.items(), key=lambda kv: -kv[1])),
        "largest_modules": dict(sorted(modules.items(), key=lambda kv: -kv[1])[:top]),
        "ros_modules": {k: v for k, v in sorted(modules.items(), key=lambda kv: -kv[1]) if k.startswith("bev_mdo/ros/")},
        "longest_functions": functions[:top],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=str(REPO))
    ap.add_argument("--json", default=None)
    ap.add_argument("--top", type=int, default=10)
    args = ap.parse_args()
    out = measure(Path(args.root), args.top)
    text = json.dumps(out, indent=2)
    print(text)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
