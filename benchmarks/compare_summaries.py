"""Does a re-run reproduce the same science? Every headline number of a new `reproduce_summary` file against an old one.

    python -m benchmarks.compare_summaries OLD.json NEW.json --name NAME

For each number both files hold (adaptation AUC, start and end return; zero-shot return;
marginal distance; held-out score; per population and method), prints the old interval, the new mean and
interval, whether the new mean lies inside the old interval and whether the two intervals
overlap. Writes `benchmarks/results/<NAME>.json`. The speed issue's check: after a change
to how training runs, every headline number of the committed reports lies inside the old
95% interval, or the difference is explained.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from benchmarks._common import write_result

METRICS = {
    "adaptation": ("auc", "start", "end"),
    "zeroshot": ("return",),
    "marginals": ("distance",),
    "heldout": ("score",),  # per agent against the held-out population
}


def _numbers(summary: dict) -> dict[tuple[str, str, str, str], dict]:
    """(section, population, method, metric) -> its {mean, lo, hi, n}."""
    return {
        (section, row["population"], row["method"], metric): row[metric]
        for section, metrics in METRICS.items()
        for row in summary.get(section, [])
        for metric in metrics
        if metric in row
    }


def compare(old: dict, new: dict) -> list[dict]:
    """One row per number both summaries hold: old and new intervals, inside and overlap flags."""
    a, b = _numbers(old), _numbers(new)
    rows = []
    for key in sorted(a.keys() & b.keys()):
        o, n = a[key], b[key]
        rows.append(
            {
                "section": key[0],
                "population": key[1],
                "method": key[2],
                "metric": key[3],
                "old": o,
                "new": n,
                "new_mean_inside_old_interval": bool(o["lo"] <= n["mean"] <= o["hi"]),
                "intervals_overlap": bool(o["lo"] <= n["hi"] and n["lo"] <= o["hi"]),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path, help="the committed reproduce_<name>.json")
    parser.add_argument("new", type=Path, help="the re-run's reproduce_<name>.json")
    parser.add_argument("--name", required=True, help="results file name: benchmarks/results/<name>.json")
    args = parser.parse_args()
    for path in (args.old, args.new):
        if not path.is_file():
            parser.error(f"{str(path)!r} is not a file")
    old, new = (json.loads(p.read_text()) for p in (args.old, args.new))
    rows = compare(old, new)
    fmt = lambda ci: f"{ci['mean']:.3f} [{ci['lo']:.3f}, {ci['hi']:.3f}] n={ci['n']}"  # noqa: E731
    print(f"{'section':<10} {'population':<22} {'method':<22} {'metric':<8} {'old':<30} {'new':<30} inside overlap")
    for r in rows:
        print(
            f"{r['section']:<10} {r['population']:<22} {r['method']:<22} {r['metric']:<8} {fmt(r['old']):<30} {fmt(r['new']):<30} {'yes' if r['new_mean_inside_old_interval'] else 'NO':<6} {'yes' if r['intervals_overlap'] else 'NO'}"
        )
    inside = sum(r["new_mean_inside_old_interval"] for r in rows)
    overlap = sum(r["intervals_overlap"] for r in rows)
    print(f"\n{len(rows)} numbers: new mean inside the old interval {inside}, intervals overlap {overlap}")
    path = write_result(
        args.name,
        {
            "old": str(args.old),
            "new": str(args.new),
            "old_stages": old.get("stages"),
            "new_stages": new.get("stages"),
            "numbers": len(rows),
            "inside": inside,
            "overlap": overlap,
            "rows": rows,
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
