"""Chains of runs: a phase's guess taken from another problem file's solution (or a run
folder) through a registered change of variables (docs/problem-language.md, "Chains").

``guess: {from: other.yaml, transform: NAME, reuse: RUN_DIR}``:

* :mod:`.registry`: the transforms by name (``@register_transform``; entry-point group
  ``ocdsl.transforms`` for other packages), like the models' registry;
* :mod:`.check`: what ``ocdsl check`` says of a chain (missing file, unknown transform,
  cycle), with the file and line;
* :mod:`.stages`: running it: the source solved first into ``RUN/stages/<stem>/`` (or an
  earlier run folder of the same source file reused), converted into ``RUN/stages/<stem>.guess/``,
  and the phase started from that.
"""
