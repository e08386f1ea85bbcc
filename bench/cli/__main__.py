"""``python -m bench.cli``: the ``hftrace`` command."""
import sys

from . import main

sys.exit(main())
