"""The subcommands. To add one, write a module with NAME, HELP,
add_arguments(parser) and run(ctx) (see common.py for the shared options
and helpers) and list it here."""
from danprobe.commands import configure, discover, sniff

COMMANDS = (discover, configure, sniff)
