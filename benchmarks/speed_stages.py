"""Per-stage wall time of ``diagnose`` on the floor-winch 8-cable case (issue 37's speed goal).

Used by ``python -m benchmarks.speed --only stages [--baseline REV] [--seed S]``. Each tree
runs in its own fresh process (:func:`worker`), which diagnoses the same recording twice: the
first run pays the JIT compilation (traced and compiled functions, counted from JAX's own
compile events) and the second does not, so their difference is the compile time. The stages
are the diagnosis' own functions, wrapped by name in the pipeline's namespace (a timing
instrument, not an interface: a stage missing in a tree is skipped); time spent in a stage
nested in another is counted for the inner one. The primitives (the linearisation, the
refits, the held-out CV, the joint clock profile) are timed wherever they are called, so they
overlap the stages. The worker also writes the findings, so that the trees' results are
compared number by number.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

#: (label, function name in the pipeline's namespace), in the pipeline's order
STAGES = (
    ("prepare: align, differentiate, masks", "prepare"),
    ("episodes", "find_episodes"),
    ("lengths stream", "lengths_stream"),
    ("base fit + noise levels", "base_fit"),
    ("base fit + noise levels", "noise_levels"),
    ("clock profile (first stage)", "clock_stage"),
    ("null replicates", "null_residuals"),
    ("forward steps: screening + refits", "forward_step"),
    ("clock check after each step", "clock_check"),
    ("swap stage", "swap_stage"),
    ("second start (best pair)", "pair_start"),
    ("backward elimination", "backward_stage"),
    ("stability", "stability_stage"),
    ("geometry vs sensor side", "geometry_stage"),
    ("plausibility", "plausibility_stage"),
    ("clock interval (final joint profile)", "clock_interval"),
    ("competing models", "competing_models"),
    ("competing models", "adopt_better"),
    ("unexplained", "_structure"),
    ("unexplained", "unexplained_stage"),
    ("elasticity", "with_elasticity"),
    ("report: summary (held-out CV, BIC)", "summarize"),
    ("report: not named sizes", "not_named_sizes"),
    ("report: verdict", "verdict"),
    ("report: episodes' held-out rms", "_with_episodes"),
)
#: (label, module, function): timed wherever called (inclusive, overlapping the stages)
PRIMITIVES = (
    ("nonlinear refit (Gauss-Newton)", "_selection", "refit"),
    ("linearisation (design)", "_problem", "design"),
    ("cable side + Jacobian", "_problem", "cable_side"),
    ("joint clock profile", "_profile", "joint_delay"),
    ("held-out CV (heldout_rms)", "_problem", "heldout_rms"),
)
_COMPILE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration",
                   "/jax/core/compile/jaxpr_to_mlir_module_duration",
                   "/jax/core/compile/backend_compile_duration")


def _mark(wrapped, fn):
    """A timing wrapper that :func:`_uninstrument` recognises."""
    wrapped.__wrapped__, wrapped._speed_timer = fn, True
    return wrapped


class Timer:
    """Exclusive stage times, inclusive primitive times and JIT compile time per stage."""

    def __init__(self):
        self.stack: list[str] = []
        self.wall: dict[str, float] = {}
        self.compile: dict[str, float] = {}
        self.n_compiles: dict[str, int] = {}
        self.prim: dict[str, list] = {}
        self._t = time.perf_counter()

    def _switch(self):
        now = time.perf_counter()
        key = self.stack[-1] if self.stack else "(between stages)"
        self.wall[key] = self.wall.get(key, 0.0) + now - self._t
        self._t = now

    def stage(self, label, fn):
        def wrapped(*a, **k):
            self._switch()
            self.stack.append(label)
            try:
                return fn(*a, **k)
            finally:
                self._switch()
                self.stack.pop()
        return _mark(wrapped, fn)

    def primitive(self, label, fn):
        active = []

        def wrapped(*a, **k):
            if active:  # nested call of the same primitive: counted once
                return fn(*a, **k)
            active.append(1)
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                active.pop()
                v = self.prim.setdefault(label, [0.0, 0])
                v[0] += time.perf_counter() - t0
                v[1] += 1
        return _mark(wrapped, fn)

    def on_event(self, event, duration, **_):
        if event in _COMPILE_EVENTS:
            key = self.stack[-1] if self.stack else "(between stages)"
            self.compile[key] = self.compile.get(key, 0.0) + duration
            if event.endswith("backend_compile_duration"):
                self.n_compiles[key] = self.n_compiles.get(key, 0) + 1

    def as_json(self, total: float) -> dict:
        return {"total": total, "wall": self.wall, "compile": self.compile,
                "n_compiles": self.n_compiles, "primitives": self.prim}


def _instrument(timer: Timer) -> None:
    """Wrap the stages and primitives in the loaded diagnosis modules' namespaces."""
    pipe = sys.modules["cdprid.diagnosis._pipeline"]
    for label, name in STAGES:
        if hasattr(pipe, name):
            setattr(pipe, name, timer.stage(label, getattr(pipe, name)))
    mods = [m for k, m in list(sys.modules.items()) if k.startswith("cdprid.diagnosis._")]
    for label, mod, name in PRIMITIVES:
        orig = getattr(sys.modules.get(f"cdprid.diagnosis.{mod}"), name, None)
        if orig is None:
            continue
        wrapped = timer.primitive(label, orig)
        for m in mods:
            if getattr(m, name, None) is orig:
                setattr(m, name, wrapped)


def _findings(res) -> list:
    """The result's findings and headline numbers, JSON-ready (for comparing two trees)."""
    out = [{"effect": f.effect, "parameters": f.parameters, "interval": f.interval}
           for f in res.findings]
    out.append({"effect": "(held-out rms)", "parameters": {
        "base": res.base_heldout_rms, "extended": res.extended_heldout_rms}})
    out.append({"effect": "(unexplained)", "parameters": {
        str(i): u.get("size") for i, u in enumerate(res.unexplained)}})
    return json.loads(json.dumps(out, default=float))


def worker(data_dir: str, out: str, runs: int = 2) -> None:
    """Diagnose ``data_dir`` ``runs`` times in this process; write the timers as JSON."""
    import os

    import jax

    jax.config.update("jax_enable_x64", True)
    cache = os.environ.get("CDPRID_CACHE_DIR", "off")
    if cache != "off":  # the persistent compilation cache as the CLI sets it (enable_x64)
        Path(cache).mkdir(parents=True, exist_ok=True)
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    import cdprid.diagnosis  # noqa: F401  (loads the pipeline's modules)
    from cdprid.diagnosis import diagnose
    from cdprid.io import read_dataset

    results = []
    for _ in range(runs):
        timer = Timer()
        _instrument(timer)
        jax.monitoring.register_event_duration_secs_listener(timer.on_event)
        t0 = time.perf_counter()
        res = diagnose(read_dataset(Path(data_dir)))
        total = time.perf_counter() - t0
        timer._switch()
        jax.monitoring.unregister_event_duration_listener(timer.on_event)
        _uninstrument()
        results.append({**timer.as_json(total), "findings": _findings(res)})
    Path(out).write_text(json.dumps(results))


def _uninstrument() -> None:
    """Undo :func:`_instrument` (the wrappers keep their originals in ``__wrapped__``)."""
    for name, m in list(sys.modules.items()):
        if not name.startswith("cdprid.diagnosis._"):
            continue
        for k, v in list(vars(m).items()):
            if callable(v) and getattr(v, "__wrapped__", None) is not None \
                    and getattr(v, "_speed_timer", False):
                setattr(m, k, v.__wrapped__)


def max_rel_diff(a, b) -> float:
    """Largest relative difference between two JSON structures of numbers (inf when their
    shapes or keys differ)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return float("inf")
        return max((max_rel_diff(a[k], b[k]) for k in a), default=0.0)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return float("inf")
        return max((max_rel_diff(x, y) for x, y in zip(a, b, strict=True)), default=0.0)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) \
            and not isinstance(a, bool):
        return abs(a - b) / max(abs(a), abs(b), 1e-300)
    return 0.0 if a == b else float("inf")


if __name__ == "__main__":
    worker(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 2)


def run_trees(d: Path, trees: dict, seed: int, rounds: int = 1) -> dict:
    """The floor8 recording of ``seed`` (this tree's test simulator) diagnosed by each tree of
    ``trees`` (name -> its ``src``) in a fresh process (:func:`worker`, two runs), the trees
    alternated ``rounds`` times (a shared machine's load falls on all alike); each tree has
    its own persistent JAX cache. Returns {name: [worker results of each round]}."""
    import os
    import subprocess

    root = Path(__file__).resolve().parents[1]
    data = d / f"floor8_{seed}"
    code = ("import sys; from pathlib import Path; import jax; "
            "jax.config.update('jax_enable_x64', True); "  # else robot.toml in float32
            "from tests._testbench import floor8_case, write; "
            f"write(floor8_case({seed}), Path(sys.argv[1]), overwrite=True)")
    env0 = {**os.environ, "PYTHONPATH": f"{root / 'src'}{os.pathsep}{root}"}
    subprocess.run([sys.executable, "-c", code, str(data)], env=env0, check=True, cwd=root)
    out: dict = {}
    for k in range(rounds):
        for name, src in trees.items():
            env = {**os.environ, "PYTHONPATH": f"{src}{os.pathsep}{root}",
                   "CDPRID_CACHE_DIR": str(d / f"cache-{name}"), "CDPRID_QUIET": "1"}
            path = d / f"stages-{name}-{k}.json"
            subprocess.run([sys.executable, "-m", "benchmarks.speed_stages", str(data),
                            str(path)], env=env, check=True, cwd=root)
            out.setdefault(name, []).append(json.loads(path.read_text()))
            print(f"round {k + 1}: {name}: " + ", ".join(
                f"run {i + 1} {r['total']:.1f} s" for i, r in enumerate(out[name][-1])),
                flush=True)
    return out


def table(res: dict) -> list[str]:
    """Markdown rows: per stage, each tree's first run (with its JIT compile time) and second
    run (least over the rounds), and the ratio of the second runs to the first tree's."""
    names = list(res)
    best = {n: [min((r[i] for r in res[n]), key=lambda x: x["total"]) for i in (0, 1)]
            for n in names}
    labels = list(dict.fromkeys([lab for lab, _ in STAGES] + ["(between stages)"]))
    head = "| stage | " + " | ".join(
        f"{n}: run 1 [s] (compile) | {n}: run 2 [s]" for n in names) + " |"
    ratio = len(names) > 1
    lines = [head + (" ratio run 2 |" if ratio else ""),
             "|---|" + "---:|---:|" * len(names) + ("---:|" if ratio else "")]

    def cells(key, n):
        r1, r2 = best[n]
        if key is None:
            return (f"**{r1['total']:.1f}** ({sum(r1['compile'].values()):.1f}) | "
                    f"**{r2['total']:.1f}**"), r2["total"]
        w1, w2 = r1["wall"].get(key, 0.0), r2["wall"].get(key, 0.0)
        return f"{w1:.1f} ({r1['compile'].get(key, 0.0):.1f}) | {w2:.1f}", w2

    for key in labels + [None]:
        row = [cells(key, n) for n in names]
        if key is not None and max(v for _, v in row) < 0.05:
            continue
        r = (f" {row[0][1] / row[1][1]:.2f} |" if ratio and row[1][1] > 0 else
             (" |" if ratio else ""))
        lines.append(f"| {key or 'total'} | " + " | ".join(c for c, _ in row) + " |" + r)
    lines += ["", "Primitives, timed wherever called (inclusive; they overlap the stages), "
              "second run: " + "; ".join(
                  f"{n}: " + ", ".join(f"{lab} {v[0]:.1f} s ({v[1]} calls)"
                                       for lab, v in best[n][1]["primitives"].items())
                  for n in names) + "."]
    return lines


def same_findings(res: dict) -> float:
    """Largest relative difference between the findings of every run of every tree and the
    first tree's first run (inf when the findings differ in kind)."""
    first = next(iter(res.values()))[0][0]["findings"]
    return max(max_rel_diff(first, r["findings"]) for rounds in res.values()
               for runs in rounds for r in runs)
