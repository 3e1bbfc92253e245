"""``python -m starid`` is the ``starid`` command."""

from .cli import main

raise SystemExit(main())
