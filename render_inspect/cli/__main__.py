"""``python -m render_inspect.cli``: the ``render-inspect`` command."""

import sys

from . import main

sys.exit(main())
