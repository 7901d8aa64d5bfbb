"""Fuzzing the problem language (issue 27): mutated ``configs/`` files through the project's
compile entry (what ``ocdsl check`` runs), each ending in one of

  accepted           compiled without an error
  error with line    SpecError whose every issue names a line
  error, no line     SpecError with an issue that names no line (a failure of this harness)
  <ExceptionType>    anything else (a failure)
  over 5 s           more than 5 s of CPU time (a failure)

``python tests/fuzzing.py [--files N] [--seed S] [--limit SECONDS]`` prints the table (class
and count) and the worst cases; ``make fuzz`` runs 10,000 files. tests/test_hostile_input.py
runs a few hundred of the same cases in CI, and a hypothesis property on expressions.
"""
from __future__ import annotations

import argparse
import collections
import random
import re
import resource
import signal
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"

# hostile values dropped into number and expression slots
NUMBERS = [".nan", ".inf", "-.inf", "0", "-1", "1e999", "-0.0", "1e-320", "9" * 400, "9" * 5000,
           "0x" + "f" * 300, "true", "null", "[]", "{}", "'1'", "1_000", "2024-01-01", "~"]
EXPRESSIONS = [
    "__import__('os').system('true')", "u.__class__", "().__class__", "lambda: 0", "[x for x in y]",
    "sqrt(-1)", "log(-2)", "acos(2)", "1/0", "x/0", "(((9**64)**64)**64)**64", "9**9**9**9",
    "2**64**64", "10**300*10**300*10**300", "1e308*1e308", "x**(1/0)",
    " + ".join(["x"] * 500), "*".join(["x"] * 500), "sin(" * 150 + "x" + ")" * 150,
    "(" * 300 + "x" + ")" * 300, "-" * 2000 + "x", "x" + "**x" * 300, "9" * 5000, "9" * 301,
    "pi", "inf", "-inf", "t", "tf", "t0", "integral(integral(x))", "x(tf)(tf)", "x(t1)",
    "norm(x)", "dot([1, 2], [1, 2, 3])", "cross([1, 2], [3, 4])", "[x, x][5]", "[x][0]",
    "x == 1", "x <= 1 <= 0", "x < 1", "1 <= 2", "", " ", "\u00e9", "x\x00", "%s" % ("a" * 21000),
    "continuous(a)", "abs()", "sin(1, 2)", "atan2(1)", "exp(1000)", "exp(exp(exp(10)))",
]
NAMES = ["pi", "e", "E", "I", "N", "S", "t", "tf", "sin", "integral", "objective", "lambda", "None",
         "True", "__class__", "x.y", "1x", "", "main", "continuous", "inf", "nan", "oo", "zoo",
         "integral1_main", "a" * 300]
YAML_SNIPPETS = [
    "!!python/object/apply:os.system ['true']", "!!python/name:os.system", "!custom 1",
    "!!binary aGVsbG8=", "!!set {a, b}", "!!omap [a: 1]", "!!timestamp 2024-01-01", "&a [1, *a]",
    "*undefined", "<<: {}", "[" * 2000 + "]" * 2000, "{" * 100 + "}" * 100, "|\n  block", ">\n  folded",
    "'unterminated", "\"\\x\"", "\t", "- [1, 2", "{a: 1, a: 2}", "? [a, b]\n: 1",
]
BOMB = ("definitions:\n  a: &a [x, x, x, x, x, x, x, x, x]\n" +
        "".join(f"  {c}: &{c} [{', '.join([f'*{p}'] * 9)}]\n" for p, c in zip("abcdefgh", "bcdefghi")))


def corpus() -> list[tuple[str, str]]:
    return [(p.name, p.read_text()) for p in sorted(CONFIGS.glob("*.yaml"))]


def mutate(text: str, rng: random.Random) -> str:
    """One to three random mutations of a problem file's text."""
    for _ in range(rng.choice((1, 1, 2, 3))):
        text = rng.choice(MUTATIONS)(text, rng)
    return text


def _lines(text):
    return text.split("\n")


def m_number(text, rng):
    nums = list(re.finditer(r"(?<![\w.])-?\d+(\.\d+)?(e-?\d+)?(?![\w.])", text))
    if not nums:
        return text
    m = rng.choice(nums)
    return text[:m.start()] + rng.choice(NUMBERS) + text[m.end():]


def m_expression(text, rng):
    """Replace the value after a key, or a list item, with a hostile expression."""
    slots = list(re.finditer(r"(?m)(^\s*- |: )([^\n{}\[\]#]+)$", text))
    if not slots:
        return text
    m = rng.choice(slots)
    e = rng.choice(EXPRESSIONS)
    if rng.random() < 0.5 and "==" not in e:
        e = f"{m.group(2).strip()} + {e}" if rng.random() < 0.5 else f"x(t0) == {e}"
    quoted = '"' + e.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return text[:m.start(2)] + quoted + text[m.end(2):]


def m_name(text, rng):
    names = sorted(set(re.findall(r"\b[A-Za-z_]\w*\b", text)))
    if not names:
        return text
    old = rng.choice(names)
    return re.sub(rf"\b{re.escape(old)}\b", rng.choice(NAMES), text, count=rng.choice((1, 0)))


def m_yaml(text, rng):
    lines = _lines(text)
    i = rng.randrange(len(lines))
    if ":" in lines[i] and rng.random() < 0.7:
        key, _, _ = lines[i].partition(":")
        lines[i] = f"{key}: {rng.choice(YAML_SNIPPETS)}"
    else:
        lines.insert(i, rng.choice(YAML_SNIPPETS))
    return "\n".join(lines)


def m_lines(text, rng):
    lines = _lines(text)
    i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
    op = rng.choice(("delete", "duplicate", "swap", "indent", "dedent"))
    if op == "delete":
        del lines[i]
    elif op == "duplicate":
        lines.insert(j, lines[i])
    elif op == "swap":
        lines[i], lines[j] = lines[j], lines[i]
    elif op == "indent":
        lines[i] = "  " + lines[i]
    else:
        lines[i] = lines[i].lstrip()
    return "\n".join(lines)


def m_bytes(text, rng):
    if not text:
        return text
    i = rng.randrange(len(text))
    op = rng.choice(("truncate", "flip", "insert"))
    if op == "truncate":
        return text[:i]
    ch = rng.choice("{}[]:,-&*!|>'\"#%@`\t\n\\ 0.e")
    return text[:i] + ch + text[i + (op == "flip"):]


def m_bomb(text, rng):
    return BOMB + text.replace("name:", "name2: *i\nname:", 1) if rng.random() < 0.5 else BOMB + text


def m_big(text, rng):
    """Many items: a long constraint list, many states or a huge study."""
    op = rng.choice(("constraints", "states", "study", "value"))
    if op == "constraints" and "constraints:\n" in text:
        return text.replace("constraints:\n", "constraints:\n" + "    - x(t0) <= 1\n" * rng.choice((100, 900, 5000)), 1)
    if op == "states" and "states: [" in text:
        many = ", ".join(f"s{i}" for i in range(rng.choice((50, 1500))))
        return text.replace("states: [", f"states: [{many}, ", 1)
    if op == "study":
        return text + "\nstudy:\n  sweep:\n    grid:\n      k: {start: 0, stop: 1, num: 200000000}\n"
    return text + f"\ndefinitions: {'[' * 39}{'1, ' * 9500}{']' * 39}\n"


MUTATIONS = [m_number, m_number, m_expression, m_expression, m_expression, m_name, m_yaml,
             m_lines, m_bytes, m_bytes, m_bomb, m_big]


# -- running one case -------------------------------------------------------------------
class _Timeout(BaseException):
    """Raised by the alarm; a BaseException so that no ``except Exception`` swallows it."""


def _alarm(signum, frame):
    raise _Timeout()


def check_text(text: str, path: Path) -> None:
    """What ``ocdsl check`` does with a file: the Pareto loader for ``pareto:`` files, the
    study loader for ``study:`` blocks, else the compile entry."""
    from ocdsl.api import compile_file
    from ocdsl.spec.loader import load_yaml

    path.write_text(text, errors="surrogateescape")
    data = load_yaml(path).data
    if "pareto" in data:
        from ocdsl.spec.pareto import load_pareto

        load_pareto(path)
        return
    compile_file(path)
    if "study" in data:
        from ocdsl.study.spec import load_study

        load_study(path)


def classify(text: str, path: Path, limit: float = 5.0) -> tuple[str, float, str]:
    """(class, seconds, message) of one case."""
    from ocdsl.spec.errors import SpecError
    from ocdsl.study.spec import StudyError

    # the limit is CPU time (ITIMER_PROF): on a shared machine wall time measures the load;
    # a wall-clock alarm of 12x the limit still ends a case that waits without computing
    signal.signal(signal.SIGPROF, _alarm)
    signal.signal(signal.SIGALRM, _alarm)
    t = time.perf_counter()
    signal.setitimer(signal.ITIMER_PROF, limit)
    signal.setitimer(signal.ITIMER_REAL, 12 * limit)
    try:
        check_text(text, path)
        kind, message = "accepted", ""
    except _Timeout:
        kind, message = "over 5 s", ""
    except SpecError as e:
        kind = "error with line" if all(i.line for i in e.issues) else "error, no line"
        message = str(e)
    except StudyError as e:
        kind = "error with line" if e.line else "error, no line"
        message = str(e)
    except BaseException as e:   # noqa: BLE001 - this is what the harness is for
        if isinstance(e, KeyboardInterrupt):
            raise
        kind, message = type(e).__name__, f"{type(e).__name__}: {e}"[:300]
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.setitimer(signal.ITIMER_REAL, 0)
    return kind, time.perf_counter() - t, message


GOOD_CLASSES = ("accepted", "error with line")


def cases(n: int, seed: int, names: tuple[str, ...] | None = None):
    """``n`` mutated files (name, text), deterministic from ``seed``."""
    rng = random.Random(seed)
    base = [c for c in corpus() if names is None or c[0] in names]
    for i in range(n):
        name, text = base[i % len(base)]
        yield f"{name}#{i}", mutate(text, rng)


def run(n: int, seed: int, limit: float, workdir: Path, names=None, log=None, skip: int = 0) -> collections.Counter:
    table: collections.Counter = collections.Counter()
    worst: list[tuple[float, str, str]] = []
    for k, (case, text) in enumerate(cases(n, seed, names)):
        if k < skip:          # the same sequence, from case ``skip`` on (runs split across processes)
            continue
        kind, seconds, message = classify(text, workdir / "problem.yaml", limit)
        table[kind] += 1
        worst.append((seconds, case, kind))
        if log is not None and kind not in GOOD_CLASSES:
            (log / f"{kind.replace(' ', '_')}_{k}.yaml").write_text(text, errors="surrogateescape")
            print(f"{case}: {kind}: {message.splitlines()[0] if message else ''}"[:240], flush=True)
    worst.sort(reverse=True)
    print("\nclass                 count")
    for kind, count in table.most_common():
        print(f"{kind:20s} {count:6d}")
    print(f"{'total':20s} {sum(table.values()):6d}")
    print("slowest: " + ", ".join(f"{c} {s:.2f} s ({k})" for s, c, k in worst[:5]))
    return table


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--files", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=27)
    ap.add_argument("--limit", type=float, default=5.0, help="seconds per case")
    ap.add_argument("--log", type=Path, default=None, help="folder to keep the failing cases in")
    ap.add_argument("--skip", type=int, default=0, help="start at this case (split a run across processes)")
    args = ap.parse_args(argv)
    # a memory bomb ends as MemoryError in its case, not as the machine's OOM killer
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, resource.RLIM_INFINITY))
    import tempfile

    if args.log:
        args.log.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as d:
        table = run(args.files, args.seed, args.limit, Path(d), log=args.log, skip=args.skip)
    bad = sum(v for k, v in table.items() if k not in GOOD_CLASSES)
    print(f"\n{bad} cases outside 'accepted' / 'error with line'")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
