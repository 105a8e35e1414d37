"""Equations as readable as the paper's (issue 11): for every bundled model, each printed
entry of ``Mbar``, ``hbar``, ``fbar`` is no longer than what sympy's simplifiers make of it
and than the paper's (22), (23), (29); no identity or needless multiple angle survives;
repeated subexpressions are named once; everything printed parses back to the same value;
the LaTeX fits the page."""
from __future__ import annotations

import os
import random
import re
import shutil
import subprocess
import sys

import pytest
import sympy
from sympy import cos, sin, sqrt

from conftest import MODELS
from helpers import S
from helpers.readable import (BUNDLED, EXTRA, PARSEABLE, YARDSTICK_MODELS, YARDSTICK_OPS, entries, printed,
                              system_of, yardstick_key, yardsticks)
from kronsub.emitters.latex_layout import WIDTH, measure
from kronsub.emitters.report import model_names, plain_printer
from kronsub.emitters.text import emit_latex
from kronsub.model.expressions import parse_expression

def inline(expr, report, names):
    """``expr`` with the where block's names replaced by what they stand for."""
    for w in reversed(report["where"]):
        expr = expr.xreplace({names[w["plain"]]: parse_expression(w["expression"], names)})
    return expr


def same_value(a, b, seed=11) -> bool:
    """Equal at random points (parameters and coordinates in 0.3..0.9), to 20 digits."""
    rng = random.Random(seed)
    symbols = sorted(a.free_symbols | b.free_symbols, key=lambda s: s.name)
    for _ in range(3):
        point = {s: sympy.Rational(rng.randint(300, 900), 1000) for s in symbols}
        x, y = a.evalf(30, subs=point), b.evalf(30, subs=point)
        if abs(x - y) > sympy.Float(1e-20) * (1 + abs(y)):
            return False
    return True


@pytest.mark.parametrize("name", PARSEABLE + EXTRA)
def test_every_printed_expression_parses_back_to_the_same_value(name):
    system, report, names = printed(name)
    wanted = [*[system.mass_matrix[i, j] for i in range(system.mass_matrix.rows)
                for j in range(i, system.mass_matrix.cols)], *system.velocity_terms, *system.forces]
    for (label, text), want in zip(entries(report), wanted):
        got = inline(parse_expression(text, names), report, names)
        assert same_value(got, want), f"{name} {label}: {text}"
    texts = [report["kinetic_energy"], report["potential_energy"],
             *[e for eff in report["effects"] for e in eff["forces"]],
             *[side for eq in report["equations"] for side in (eq["lhs"], eq["rhs"])]]
    texts += [t for p in report.get("primitive", {}).get("metric", []) for t in p]
    for text in texts:  # every function sympy printed is one the parser knows
        parse_expression(text, names)


@pytest.mark.parametrize("name", ["sweep3/two_tops.yaml",
                                  "sweep5/line_plane_space.yaml"])
def test_by_effect_uses_the_where_names(name):
    """Each effect's row of ``fbar`` uses the names of the where block, as ``fbar`` itself does:
    cells as short as ``fbar``'s, and each the effect's force when the names are put back."""
    system, report, names = printed(name)
    assert report["where"] and len(report["effects"]) > 1
    used = 0
    for effect, (key, forces) in zip(report["effects"], system.effect_forces.items()):
        assert effect["name"] == key
        for text, want in zip(effect["forces"], forces):
            got = parse_expression(text, names)
            used += any(s.name in {w["plain"] for w in report["where"]} for s in got.free_symbols)
            assert same_value(inline(got, report, names), want), f"{name} {key}: {text}"
    assert used
    longest = max(len(f) for f in report["forces"])
    assert max(len(f) for e in report["effects"] for f in e["forces"]) <= longest


def test_abs_and_euler_number_print_in_the_model_language():
    x = S("x")
    show = plain_printer({"E", "pi"})
    assert show(sympy.Abs(x + 1)) == "abs(x + 1)"
    assert show(sympy.E * x) == "exp(1)*x"
    assert show(sympy.pi * x) == "acos(-1)*x"  # the model's own pi is another name
    assert plain_printer()(sympy.pi * x) == "pi*x"
    names = {"x": x, "E": S("E"), "pi": S("pi")}
    for e in (sympy.Abs(x + 1) * sympy.sign(x), sympy.E * x + sympy.pi, sympy.Heaviside(x - 1)):
        assert same_value(parse_expression(show(e), names), e)


YARDSTICK_MODELS = [pytest.param(name, marks=pytest.mark.xfail(strict=True, reason=(
    "the loop inductance of two machines prints 2*Laa0 + Laa2*cos(2*th1) + Laa2*cos(2*th2): the sum's "
    "common factor Laa2 is not collected (fu: 8 ops against 9)"))) if name == "electrical/machine_pair.yaml"
    else name for name in YARDSTICK_MODELS]


@pytest.mark.parametrize("name", YARDSTICK_MODELS)
def test_no_printed_entry_is_shortened_by_sympys_simplifiers(name):
    """The printed entry (named subexpressions as the names they are printed as) against
    ``sympy.trigsimp`` and ``sympy.fu`` of it (as stored in ``tests/data/yardsticks.json`` for
    this very text and sympy version, else measured now)."""
    _, report, names = printed(name)
    checked = 0
    for label, text in entries(report):
        expr = parse_expression(text, names)
        ops = sympy.count_ops(expr)
        if ops > YARDSTICK_OPS:
            continue  # fu factorises: on a large entry it runs for minutes (the next test still applies)
        trig, fu = yardsticks(expr, yardstick_key(name, label, text))
        assert ops <= min(trig, fu), f"{name} {label}: {text} ({ops} ops; trigsimp {trig}, fu {fu})"
        checked += 1
    assert checked, f"{name}: no entry small enough for the yardsticks"


@pytest.mark.parametrize("name", PARSEABLE + ["disc_on_incline.yaml", "top_3d.yaml"])
def test_no_identity_and_no_multiple_angle_where_powers_are_shorter(name):
    """Neither ``sin(a)^2 + cos(a)^2`` nor a ``cos(2a)`` whose power form is shorter survives."""
    _, report, names = printed(name)
    for label, text in entries(report):
        expr = parse_expression(text, names)
        ops = sympy.count_ops(expr)
        args = sorted({f.args[0] for f in expr.atoms(sin, cos)}, key=sympy.default_sort_key)
        for a in args:
            for rewritten in (expr.subs(cos(a) ** 2, 1 - sin(a) ** 2), expr.subs(sin(a) ** 2, 1 - cos(a) ** 2)):
                assert sympy.count_ops(sympy.expand(rewritten)) >= ops or sympy.count_ops(rewritten) >= ops, \
                    f"{name} {label}: {text}"
        multiple = [f for f in expr.atoms(sin, cos) if sympy.Add.make_args(f.args[0])[0].as_coeff_Mul()[0] != 1
                    or any(abs(t.as_coeff_Mul()[0]) != 1 for t in sympy.Add.make_args(f.args[0]))]
        if not multiple:
            continue
        powers = sympy.expand_trig(expr)
        for form in (powers, sympy.factor_terms(powers)):
            assert sympy.count_ops(form) >= ops, f"{name} {label}: {text} vs {form}"


def test_watt_governor_and_rolling_disc_print_their_power_forms():
    """The issue's examples: ``2*l**2*m*sin(alpha)**2``, not ``l**2*m*(-cos(2*alpha) + 1)``;
    ``3*m/2``, not ``m*(2*sin(alpha)**2 + 2*cos(alpha)**2 + 1)/2``."""
    _, watt, _ = printed("examples/watt_governor.yaml")
    assert "cos(2*alpha)" not in watt["mass_matrix"][0][0]
    J, l, m, alpha = S("J l m alpha")
    assert parse_expression(watt["mass_matrix"][0][0], {"J": J, "l": l, "m": m, "alpha": alpha}) \
        == J + 2 * l**2 * m * sin(alpha) ** 2
    _, disc, names = printed("disc_on_incline.yaml")
    assert parse_expression(disc["mass_matrix"][0][0], names) == 3 * S("m") / 2


def test_printed_entries_no_longer_than_the_papers_22_23_29():
    m1, m2, a1, a2, I1, I2, g, F, c, th, ph = S("m1 m2 a1 a2 I1 I2 g F c theta phi")
    paper = {
        "hoffmann/system1.yaml": {
            "Mbar[0,0]": I1 + m1 * a1**2 + 4 * m2 * a1**2,            # (22)
            "Mbar[0,1]": 2 * m2 * a1 * a2 * cos(th - ph),
            "Mbar[1,1]": I2 + m2 * a2**2,
            "fbar[0]": -(m1 + 2 * m2) * g * a1 * sin(th) + 2 * a1 * F * cos(th),  # (23)
            "fbar[1]": a2 * F * cos(ph) - a2 * m2 * g * sin(ph),
        },
        "hoffmann/system2.yaml": {  # (29)
            "fbar[0]": -(m1 + 2 * m2) * g * a1 * sin(th) + a1 * F * cos(th)
            + a1 * m2 * g * (c - a1 * sin(th)) * cos(th) / sqrt(a2**2 - (c - a1 * sin(th)) ** 2),
        },
    }
    for name, want in paper.items():
        _, report, names = printed(name)
        got = dict(entries(report))
        for label, expr in want.items():
            # with the named subexpressions written out: the paper names none here
            ours = sympy.count_ops(inline(parse_expression(got[label], names), report, names))
            theirs = sympy.count_ops(expr)
            assert ours <= theirs, f"{name} {label}: {got[label]} ({ours} ops) vs the paper's {expr} ({theirs})"


def test_kinetic_energy_prints_as_the_papers_24():
    """``T`` is printed as (24): one term for each entry of ``Mbar``'s upper triangle, the entry
    as printed (``1/2 (I1 + m1 a1^2 + 4 m2 a1^2) theta_dot^2 + ...``), not multiplied out; it
    is ``qdot^T Mbar qdot / 2`` for every model (its where names written out)."""
    m1, m2, a1, a2, I1, I2, th, ph = S("m1 m2 a1 a2 I1 I2 theta phi")
    thd, phd = S("theta_dot phi_dot")
    _, report, names = printed("hoffmann/system1.yaml")
    paper = (I1 + m1 * a1**2 + 4 * m2 * a1**2) * thd**2 / 2 + 2 * m2 * a1 * a2 * cos(th - ph) * thd * phd \
        + (I2 + m2 * a2**2) * phd**2 / 2
    got = parse_expression(report["kinetic_energy"], names)
    assert got == paper and sympy.count_ops(got) == sympy.count_ops(paper), report["kinetic_energy"]
    for name in PARSEABLE + EXTRA:
        system, report, names = printed(name)
        got = inline(parse_expression(report["kinetic_energy"], names), report, names)
        assert same_value(got, system.kinetic_energy), f"{name}: T = {report['kinetic_energy']}"


def test_system2_names_its_repeated_square_root_once():
    system, report, names = printed("hoffmann/system2.yaml")
    assert report["where"], "no named subexpressions"
    text = " ".join(t for _, t in entries(report))
    assert text.count("sqrt(1 -") == 0, text
    for w in report["where"]:
        assert w["plain"] not in model_names(system)
        uses = sum(len(re.findall(rf"\b{w['plain']}\b", t)) for _, t in entries(report)) + sum(
            len(re.findall(rf"\b{w['plain']}\b", v["expression"])) for v in report["where"])
        assert uses >= 2, f"{w['plain']} is used once"


def test_where_names_skip_the_models_own():
    from kronsub.emitters.report import named_subexpressions

    x, w1 = S("x w1")
    inner = sqrt(1 - sin(x) ** 2 / 3)
    named, reduced = named_subexpressions([inner + w1, inner * x], {"x", "w1"}, [x])
    assert [s.name for s, _ in named] == ["w2"]
    assert same_value(reduced[0].xreplace({named[0][0]: inner}), inner + w1)


def _latex_lines(doc: str):
    """The lines of the displays (between \\[ \\] or in align*), without the alignment marks."""
    inside = False
    for line in doc.splitlines():
        if line.startswith(("\\[", "\\begin{align")):
            inside = True
        if inside:
            yield line
        if line.endswith(("\\]", "\\end{align*}")) or line.startswith("\\end{align"):
            inside = False


@pytest.mark.parametrize("name", BUNDLED)
def test_latex_lines_fit_the_page_by_estimate(name):
    doc = emit_latex(system_of(name))
    assert "C^{t}" not in doc and "C^{\\mathsf{T}}" in doc
    for line in _latex_lines(doc):
        if "\\begin{bmatrix}" in line or line.startswith(("\\begin", "\\end")):
            continue
        assert measure(line) <= WIDTH + 8, f"{name}: {line}"


PDFLATEX = shutil.which("pdflatex")
REQUIRED = os.environ.get("KRONSUB_REQUIRE_PDFLATEX") == "1"


@pytest.mark.skipif(PDFLATEX is None and not REQUIRED,
                    reason="pdflatex not installed (CI installs texlive-latex-base and sets KRONSUB_REQUIRE_PDFLATEX=1)")
def test_latex_builds_without_overfull_lines(tmp_path):
    assert PDFLATEX is not None, "KRONSUB_REQUIRE_PDFLATEX=1 but pdflatex is not installed"
    problems = []
    for name in BUNDLED:
        stem = re.sub(r"\W", "_", name)
        (tmp_path / f"{stem}.tex").write_text(emit_latex(system_of(name)), encoding="utf-8")
        run = subprocess.run([PDFLATEX, "-interaction=nonstopmode", "-halt-on-error", f"{stem}.tex"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=120)
        log = (tmp_path / f"{stem}.log").read_text(encoding="latin-1")
        if run.returncode != 0:
            problems.append(f"{name}: pdflatex failed: {run.stdout[-500:]}")
        problems += [f"{name}: {m}" for m in re.findall(r"Overfull \\hbox \([^)]*\)[^\n]*", log)]
    assert not problems, "\n".join(problems)


def test_printed_forms_do_not_depend_on_the_hash_seed():
    code = ("import kronsub, sys; from kronsub.emitters.text import emit_markdown, emit_latex; "
            "s = kronsub.load(sys.argv[1]).derive(); print(emit_markdown(s)); print(emit_latex(s))")
    outs = set()
    for seed in ("0", "1", "12345"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        run = subprocess.run([sys.executable, "-c", code, str(MODELS / "hoffmann" / "system2.yaml")],
                             env=env, capture_output=True, text=True, timeout=300, check=True)
        outs.add(run.stdout)
    assert len(outs) == 1
