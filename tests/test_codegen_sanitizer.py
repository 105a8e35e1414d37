"""The generated C of every bundled and test model under AddressSanitizer and UBSan (issue 6, section 7).

Each model's functions are called over random states and parameters with buffers of exactly
the documented sizes on the heap (``KS_NQ``, ``KS_NY``, ``KS_NPARAM``, ``KS_NPRE``,
``KS_NPOINTS``), so a read or write past any of them, or undefined behaviour, stops the
program with a sanitizer report.
"""
from __future__ import annotations

import os
import shutil
import subprocess

import pytest

import kronsub
from conftest import ROOT
from kronsub.emitters.code import emit_c
from helpers.generated import ALL_MODELS

SANITIZE = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O0", "-g", "-fno-omit-frame-pointer",
            "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
ENV = dict(os.environ, ASAN_OPTIONS="detect_leaks=0:abort_on_error=0:halt_on_error=1",
           UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1")

DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "model.h"

static unsigned long long seed = 88172645463325252ULL;

static double uniform(double lo, double hi)
{
    seed ^= seed << 13; seed ^= seed >> 7; seed ^= seed << 17;
    return lo + (hi - lo) * (double)(seed >> 11) / 9007199254740992.0;
}

static double *exactly(int count)
{
    double *p = malloc(sizeof(double) * (size_t)(count > 0 ? count : 1));
    if (!p) exit(2);
    return p;
}

int main(void)
{
    double *y = exactly(KS_NY), *ydot = exactly(KS_NY), *z = exactly(KS_NY), *back = exactly(KS_NY);
    double *param = exactly(KS_NPARAM), *pre = exactly(KS_NPRE), *M = exactly(KS_NQ * KS_NQ);
    double *h = exactly(KS_NQ), *f = exactly(KS_NQ), *out = exactly(KS_NPOINTS);
    double sum = 0.0;
    int k, i;
    for (k = 0; k < 200; ++k) {
        double t = uniform(0.0, 2.0);
        for (i = 0; i < KS_NY; ++i) y[i] = uniform(-1.0, 1.0);
        for (i = 0; i < KS_NPARAM; ++i) param[i] = uniform(0.5, 1.5);
        ks_mass_matrix(y, param, M);
#ifdef KS_TIMED
        ks_velocity_terms(t, y, y + KS_NQ, param, h);
#else
        ks_velocity_terms(y, y + KS_NQ, param, h);
#endif
        ks_forces(t, y, y + KS_NQ, param, f);
        ks_rhs(t, y, param, ydot);
        ks_prepare(param, pre);
        ks_rhs_pre(t, y, pre, ydot);
        ks_momentum(y, param, z);
        ks_velocity(z, param, back);
        ks_rhs_canonical(t, z, param, ydot);
        ks_rhs_canonical_pre(t, z, pre, ydot);
        sum += ks_kinetic_energy(y, param) + ks_potential_energy(t, y, param) + M[0] + h[0] + f[0] + ydot[0];
#ifdef KS_TIMED
        ks_points(t, y, param, out);
#else
        ks_points(y, param, out);
#endif
        if (KS_NPOINTS > 0) sum += out[0];
    }
    if (ks_npre() != KS_NPRE) return 3;
    printf("%d %g\n", k, sum == sum ? 1.0 : 0.0);
    free(y); free(ydot); free(z); free(back); free(param); free(pre); free(M); free(h); free(f); free(out);
    return 0;
}
"""


@pytest.fixture(scope="module")
def sanitizer(tmp_path_factory):
    """Skip when gcc or its sanitizer runtime (libasan, libubsan) is missing."""
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler (gcc) on the PATH")
    folder = tmp_path_factory.mktemp("probe")
    (folder / "probe.c").write_text("int main(void) { return 0; }\n")
    build = subprocess.run(["gcc", *SANITIZE, "probe.c", "-o", "probe"], cwd=folder, capture_output=True, text=True)
    if build.returncode != 0:
        pytest.skip(f"gcc cannot build with -fsanitize=address,undefined (runtime missing?): {build.stderr.strip()}")
    run = subprocess.run([str(folder / "probe")], capture_output=True, text=True, env=ENV)
    if run.returncode != 0:
        pytest.skip(f"a sanitized program cannot run here: {run.stderr.strip()[:300]}")


@pytest.mark.parametrize("path", ALL_MODELS)
def test_generated_c_is_clean_under_sanitizers(path, tmp_path, sanitizer):
    system = kronsub.load(ROOT / path).derive()
    for generated in emit_c(system, "model", source=path):
        (tmp_path / generated.name).write_text(generated.text)
    (tmp_path / "main.c").write_text(DRIVER)
    subprocess.run(["gcc", *SANITIZE, "main.c", "model.c", "-o", "main", "-lm"], cwd=tmp_path, check=True,
                   capture_output=True, text=True)
    run = subprocess.run([str(tmp_path / "main")], capture_output=True, text=True, env=ENV, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "runtime error" not in run.stderr and "AddressSanitizer" not in run.stderr, run.stderr
    assert run.stdout.split()[0] == "200"
