"""Follow the scene through ``plan_sweep``: which s2cl modules receive it, and how often it climbs back up.

The rule (dynamic, on the built-in default scene): ``s2cl.app.plan.plan_sweep(Scene.load("default"))`` runs under
:func:`sys.setprofile`; at every call of a Python function of the package, the arguments it receives (positional,
keyword, ``*args`` items, ``**kwargs`` values, ``self``) are looked at, and a module *is visited* when one of its
functions receives a :class:`~s2cl.scene.scene.Scene` or the resolved object :class:`~s2cl.app.checks.Checked`
(by type: a scene derived from the scene counts too). A *climb* is a distinct (caller, callee) pair of functions
both handed the scene in which the caller is an engine (``s2cl.forward``, ``s2cl.sweep``, ``s2cl.retrieve``) and the
callee is above it (``s2cl.scene`` or the application layer). *Reloads*: calls of the library loader and of the
atmosphere terms beyond the first per state.

    python tools/follow_scene.py             # the counts, then the visited modules and the climbs
    python tools/follow_scene.py --optimise  # the same through a whole `optimise` run (ranking and reference too)
"""

from __future__ import annotations

import signal
import sys
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

ENGINES = ("s2cl.forward", "s2cl.sweep", "s2cl.retrieve")
ABOVE = ("s2cl.scene", "s2cl.app", "s2cl.studies", "s2cl.cli")


@dataclass
class Trace:
    """What one traced run saw."""

    modules: set[str] = field(default_factory=set)
    climbs: set[tuple[str, str]] = field(default_factory=set)
    calls: Counter = field(default_factory=Counter)

    def report(self) -> dict[str, Any]:
        terms = Counter()
        loads = self.calls["s2cl.scene.library:scene_library"]
        for key, n in self.calls.items():
            if key.startswith("s2cl.scene.terms:state_terms"):
                terms[key] += n
        return {"modules": len(self.modules), "climbs": len(self.climbs), "library_loads": loads,
                "terms_computed": sum(terms.values())}


def _arguments(frame: FrameType) -> list[Any]:
    code = frame.f_code
    n = code.co_argcount + code.co_kwonlyargcount
    names = list(code.co_varnames[:n])
    flags = code.co_flags
    if flags & 0x04:  # *args
        names.append(code.co_varnames[n])
        n += 1
    star = frame.f_locals.get(names[-1]) if flags & 0x04 else ()
    values = [frame.f_locals.get(name) for name in names[: n - (1 if flags & 0x04 else 0)]]
    values += list(star or ())
    if flags & 0x08:  # **kwargs
        values += list((frame.f_locals.get(code.co_varnames[n]) or {}).values())
    return values


def _where(frame: FrameType | None) -> str:
    return "" if frame is None else f"{frame.f_globals.get('__name__', '')}:{frame.f_code.co_name}"


def follow(run: Any) -> Trace:
    """Run ``run()`` under the profiler and record what receives the scene (see the module's docstring)."""
    from s2cl.app.checks import Checked
    from s2cl.scene.scene import Scene

    trace = Trace()
    kinds = (Scene, Checked)

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if not module.startswith("s2cl."):
            return
        here = _where(frame)
        trace.calls[here] += 1
        if not any(isinstance(v, kinds) for v in _arguments(frame)):
            return
        trace.modules.add(module)
        caller = frame.f_back
        if caller is not None and caller.f_globals.get("__name__", "").startswith(ENGINES) and module.startswith(ABOVE):
            if any(isinstance(v, kinds) for v in _arguments(caller)):
                trace.climbs.add((_where(caller), here))

    sys.setprofile(profile)
    try:
        run()
    finally:
        sys.setprofile(None)
    return trace


def plan_default() -> None:
    from s2cl.app.plan import plan_sweep
    from s2cl.scene.scene import Scene

    plan_sweep(Scene.load("default"))


def optimise_default() -> None:
    from s2cl.app.optimise import optimise

    with tempfile.TemporaryDirectory() as folder:
        optimise("default", f"{folder}/out")


def main(argv: list[str]) -> int:
    trace = follow(optimise_default if "--optimise" in argv else plan_default)
    counts = trace.report()
    print("through " + ("optimise" if "--optimise" in argv else "plan_sweep") + " of the default scene: "
          + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in counts.items()))
    for module in sorted(trace.modules):
        print(f"  visits {module}")
    for caller, callee in sorted(trace.climbs):
        print(f"  climbs {caller} -> {callee}")
    return 0


if __name__ == "__main__":
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # piped into head: stop quietly
    sys.exit(main(sys.argv[1:]))
