"""``python -m pdeface.cli``: the ``pdeface`` command."""
import sys

from . import main

sys.exit(main())
