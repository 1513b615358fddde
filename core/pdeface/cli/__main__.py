"""``python -m pdeface.cli``: the ``pdeface`` command."""
from . import run

run()
