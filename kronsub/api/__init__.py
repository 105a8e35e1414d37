"""The notebook face: :func:`load`, and :class:`System`, a derived system with names to
symbols, simulation, numeric functions, linearisation, generated code, the accuracy
experiment, animation, reactions and Jupyter display: the reach of the commands, through the
code they run.

:class:`~kronsub.core.known_system.KnownSystem` is pure data; :class:`System` is the same
data with these conveniences (as PyDy's ``System`` sits on ``KanesMethod``), each one of
the functions here: :mod:`.naming` (symbols and values by name, linearisation),
:mod:`.runs` (simulation, numeric functions, animation), :mod:`.outputs` (generated code,
accuracy, reactions, displays), :mod:`.system` (the objects). The simulation and the
emitters are imported when first used: they bring the code generators and their templates,
which deriving alone never needs.
"""
from .naming import UnknownName, linearize, names, split_assignments, symbol
from .outputs import (C_IDENTIFIER, Accuracy, accuracy, accuracy_plan, code_files, codegen, reactions, repr_latex,
                      repr_markdown)
from .runs import (ANIMATION_DEFAULTS, NumericSystem, Run, animate, model_file, numeric, run_span, scene_of,
                   settings_text, simulate)
from .sweeps import sweep
from .system import LoadedModel, System, load

__all__ = ["ANIMATION_DEFAULTS", "Accuracy", "C_IDENTIFIER", "LoadedModel", "NumericSystem", "Run", "System",
           "UnknownName", "accuracy", "accuracy_plan", "animate", "code_files", "codegen", "linearize", "load",
           "model_file", "names", "numeric", "reactions", "repr_latex", "repr_markdown", "run_span", "scene_of",
           "settings_text", "simulate", "split_assignments", "sweep", "symbol"]
