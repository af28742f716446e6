"""Count the imports written inside functions (and methods) across the ``s2cl`` package, per module.

An AST walk: an ``import`` or ``from ... import`` statement whose enclosing scope is a function counts once,
whatever it names. ``if TYPE_CHECKING:`` blocks at module level do not count (they are not inside a function).

    python tools/inner_imports.py            # the total, then each module's count and what it imports
    python tools/inner_imports.py --total    # the total only
"""

from __future__ import annotations

import ast
import signal
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "s2cl"


def inner_imports(path: Path) -> list[tuple[int, str]]:
    """(line, imported module) of each import statement inside a function of the file at ``path``."""
    found: list[tuple[int, str]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if in_function and isinstance(child, ast.Import):
                found.append((child.lineno, ", ".join(a.name for a in child.names)))
            elif in_function and isinstance(child, ast.ImportFrom):
                found.append((child.lineno, "." * child.level + (child.module or "")))
            visit(child, inside)

    visit(ast.parse(path.read_text()), False)
    return found


def count(package: Path = PACKAGE) -> dict[str, list[tuple[int, str]]]:
    """Each module (dotted name) with imports inside its functions, and those imports."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found = inner_imports(path)
        if found:
            out[name] = found
    return out


def main(argv: list[str]) -> int:
    per_module = count()
    total = sum(len(v) for v in per_module.values())
    print(f"imports inside functions: {total} in {len(per_module)} modules")
    if "--total" not in argv:
        for name, found in sorted(per_module.items(), key=lambda kv: (-len(kv[1]), kv[0])):
            print(f"{len(found):4d}  {name}: " + "; ".join(f"{mod} (l.{line})" for line, mod in found))
    return 0


if __name__ == "__main__":
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # piped into head: stop quietly
    sys.exit(main(sys.argv[1:]))
