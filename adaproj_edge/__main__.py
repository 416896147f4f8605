"""``python -m adaproj_edge``: the ``adaproj`` command."""

import sys

from adaproj_edge.cli import main

sys.exit(main())
