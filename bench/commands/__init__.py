"""One module per ``bench`` subcommand, each with ``add_parser`` and ``run``."""
