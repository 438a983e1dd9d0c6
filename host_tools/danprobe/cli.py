"""danprobe command line: the subcommands are in danprobe/commands/."""

import argparse
import os
import sys
from typing import Optional

from danprobe import __version__, gateway_client
from danprobe.commands import COMMANDS
from danprobe.commands.common import EXIT_FAIL, CliError, Context
from danprobe.master import DanError, OperationTimeout
from danprobe.port import PortError

EPILOG = """exit status: 0 success; 1 the operation failed (no answer, configure
failed, no frame heard, port I/O error); 2 bad arguments or the port cannot
be opened (missing, busy, not a serial port); 130 interrupted."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="danprobe",
        description="DAN v1 bus tool: discover, configure and sniff a DAN wire; drive the "
        "CAN-over-DAN gateway (ESCs, nodes, tunnels, raw CAN, SLCAN).",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"danprobe {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for cmd in COMMANDS:
        sp = sub.add_parser(cmd.NAME, help=cmd.HELP, description=cmd.DESCRIPTION, epilog=EPILOG)
        cmd.add_arguments(sp)
        sp.set_defaults(run=cmd.run)
    return p


def main(argv: Optional[list[str]] = None) -> int:
    args = build_parser().parse_args(argv)  # exits 2 on bad arguments
    gateway_client.register_names()  # sniff names and decodes the gateway's codes
    ctx = Context(args)
    try:
        return args.run(ctx)
    except CliError as e:
        ctx.error(str(e))
        return e.exit_code
    except OperationTimeout:
        ctx.error(f"{args.command}: timed out after {args.timeout:g} s")
        return EXIT_FAIL
    except (DanError, PortError) as e:
        ctx.error(f"{args.command}: {e}")
        return EXIT_FAIL
    except KeyboardInterrupt:
        ctx.error("interrupted")
        return 130
    except BrokenPipeError:
        # stdout closed early (| head): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_FAIL


if __name__ == "__main__":
    sys.exit(main())
