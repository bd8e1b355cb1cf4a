"""``python -m geoddp.cli``: the same as the ``geoddp`` command."""
import sys

from .main import main

sys.exit(main())
