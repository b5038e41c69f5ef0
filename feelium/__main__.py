"""``python -m feelium`` is the ``feelium`` command."""

from feelium.cli import main

raise SystemExit(main())
