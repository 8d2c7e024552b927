"""What the task modules share, one module per concern:

- :mod:`~pbrbench.tasks.common.scenes`: which scenes a task reads (library families, sweep values);
- :mod:`~pbrbench.tasks.common.inputs`: how a task makes an algorithm's inputs (grey levels,
  camera noise with a per-job generator, block means, the evaluation domain);
- :mod:`~pbrbench.tasks.common.figures`: display images, error maps and profile plots for the report;
- :mod:`~pbrbench.tasks.common.scoring`: the guarded algorithm call, output checks, the score book.

Conditions (``local+noise0.01``) are parsed by :func:`pbrbench.tasks.base.parse_condition`.  This is
a package, not a task module: task discovery (:func:`pbrbench.tasks.task_names`) lists modules only.
"""
