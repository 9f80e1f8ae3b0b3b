"""The command line: ``python -m simbench`` (Hydra runs and sweeps) and its subcommands, terminal output."""
