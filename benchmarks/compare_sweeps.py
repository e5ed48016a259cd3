"""Compare two JSONL logs of benchmarks/diagnosis.py run by run: the same keys, outcomes,
findings and finding parameters (usage: python -m benchmarks.compare_sweeps A.jsonl B.jsonl)."""

import json
import sys


def load(path) -> dict:
    """Records by key (lines that are not JSON, e.g. cut by a kill, are skipped)."""
    out = {}
    for line in open(path):
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if "key" in rec:
            out[rec["key"]] = rec
    return out


def findings(rec) -> list:
    return [(f.get("effect"), json.dumps(f.get("parameters"), sort_keys=True))
            for f in rec.get("found", [])]


def main() -> int:
    a, b = load(sys.argv[1]), load(sys.argv[2])
    print("runs", len(a), len(b), "same keys", set(a) == set(b))
    diff = [k for k in sorted(a) if a[k].get("outcome") != b.get(k, {}).get("outcome")
            or findings(a[k]) != findings(b.get(k, {}))]
    print("records with different outcome or findings:", len(diff), diff[:5])
    worst = 0.0
    for k in a:
        fb = b.get(k, {}).get("found", [])
        for fa, fbb in zip(a[k].get("found", []), fb, strict=False):
            for key, va in (fa.get("parameters") or {}).items():
                vb = fbb["parameters"].get(key)
                if isinstance(va, (int, float)) and isinstance(vb, (int, float)) and va:
                    worst = max(worst, abs(va - vb) / abs(va))
    print("largest relative difference of a finding's parameter:", worst)
    return 0


if __name__ == "__main__":
    sys.exit(main())
