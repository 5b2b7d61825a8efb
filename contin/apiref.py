"""The README's API reference: every public function and class of the user-facing modules with
the first line of its docstring.

``python -m contin.apiref`` prints the Markdown that README.md carries between the markers
``<!-- api-reference:start -->`` and ``<!-- api-reference:end -->`` (``--write`` puts it there);
tests/test_readme_api.py checks that the two agree, so the reference cannot drift from the code.  Public means: the
module's ``__all__`` when it has one, else every function or class defined in the module whose
name does not start with an underscore.  A new user-facing module goes into :data:`MODULES`.
"""

from __future__ import annotations

import importlib
import inspect

#: user-facing modules, in reading order (the CLI, plotting internals and helpers are not listed)
MODULES = (
    "contin",
    "contin.continuation",
    "contin.problem",
    "contin.fromfunctions",
    "contin.options",
    "contin.branch",
    "contin.io",
    "contin.autoformat",
    "contin.restart",
    "contin.verify",
    "contin.plot",
    "contin.stability",
    "contin.twoparam",
    "contin.foldcurve",
    "contin.hopfcurve",
    "contin.cycles",
    "contin.lpccurve",
    "contin.orbitprofile",
    "contin.diagram",
    "contin.bpfit",
    "contin.fit",
    "contin.normalform",
    "contin.scene",
)

START = "<!-- api-reference:start -->"
END = "<!-- api-reference:end -->"


def public_names(module_name: str) -> list[str]:
    """Public functions and classes of one module (module docstring)."""
    mod = importlib.import_module(module_name)
    if hasattr(mod, "__all__"):
        return [n for n in mod.__all__ if not n.startswith("_") and (inspect.isfunction(getattr(mod, n))
                                                                      or inspect.isclass(getattr(mod, n)))]
    return sorted(n for n, obj in vars(mod).items()
                  if not n.startswith("_") and (inspect.isfunction(obj) or inspect.isclass(obj))
                  and getattr(obj, "__module__", None) == module_name)


def summary(obj: object) -> str:
    """First line of the docstring ('(no docstring)' if none)."""
    doc = inspect.getdoc(obj) or ""
    return doc.strip().splitlines()[0].strip() if doc.strip() else "(no docstring)"


def markdown() -> str:
    """The reference as Markdown (one table row per public name)."""
    lines = [START, ""]
    for name in MODULES:
        mod = importlib.import_module(name)
        names = public_names(name)
        if not names:
            continue
        lines += [f"**`{name}`** — {summary(mod)}", "", "| name | summary |", "|---|---|"]
        for n in names:
            obj = getattr(mod, n)
            kind = "class" if inspect.isclass(obj) else "def"
            text = summary(obj).replace("|", "\\|")
            lines.append(f"| `{n}` ({kind}) | {text} |")
        lines.append("")
    lines.append(END)
    return "\n".join(lines)


def write_readme(path: str = "README.md") -> bool:
    """Replace the reference between the markers in ``path``; True if the file changed."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    i, j = text.index(START), text.index(END) + len(END)
    new = text[:i] + markdown() + text[j:]
    if new != text:
        with open(path, "w", encoding="utf-8") as f:
            f.write(new)
    return new != text


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["--write"]:
        print("README.md updated" if write_readme() else "README.md already up to date")
    else:
        print(markdown())
