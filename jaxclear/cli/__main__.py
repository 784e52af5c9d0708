"""``python -m jaxclear.cli``: the same as the ``jaxclear`` command."""

import sys

from ._main import main

sys.exit(main())
