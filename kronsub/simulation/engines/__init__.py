"""The engines of the integration methods, one module each: ``c`` (the methods wholly in C),
``scipy`` (scipy's solvers on the compiled right-hand side), ``taylor`` (a Taylor integrator
generated as C) and ``heyoka``. Each ``blocks`` generator yields the rows ``(t, Y)`` of a run on
its output grid and records on the :class:`~kronsub.simulation.rows.Run` how it ended; the
method table (:mod:`..methods`) says which engine runs which method."""
