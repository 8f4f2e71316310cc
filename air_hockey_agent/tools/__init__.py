"""The ``air-hockey`` command line and its subcommands."""
