"""danprobe command line: the subcommands are in danprobe/commands/."""

import argparse
import os
import re
import sys
from typing import Optional

from danprobe import __version__, gateway_client
from danprobe.commands import COMMANDS
from danprobe.commands.common import EXIT_FAIL, EXIT_INTERRUPTED, CliError, Context
from danprobe.file_update import Stopped
from danprobe.master import DanError, OperationTimeout
from danprobe.port import PortError

EPILOG = """exit status: 0 success; 1 the operation failed (no answer, configure
failed, no frame heard, port I/O error); 2 bad arguments or the port cannot
be opened (missing, busy, not a serial port); 130 interrupted."""


class Parser(argparse.ArgumentParser):
    """argparse, but every token that starts with '-' and a digit (or '-.'
    and a digit) is a value, never an option: `esc --values -8192,-1,0`,
    `esc --ramp -10%:10%`, `param set NAME -1e3`. Plain argparse (before
    Python 3.13) takes only a lone number (-5, -1.5) for a value and any
    other such token for an unknown option ("expected one argument"). No
    danprobe option starts with '-' and a digit, so none is shadowed.
    Subcommand parsers are of this class too (add_subparsers' default)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")


class HelpFormatter(argparse.HelpFormatter):
    """argparse's, but lines that start with a space (the examples) are
    kept as they are; the other lines are filled as usual."""

    def _fill_text(self, text, width, indent):
        out, para = [], []

        def flush():
            if para:
                out.append(super(HelpFormatter, self)._fill_text(" ".join(para), width, indent))
                para.clear()

        for line in text.splitlines():
            if line.startswith(" ") or not line.strip():
                flush()
                out.append(indent + line)
            else:
                para.append(line)
        flush()
        return "\n".join(out)


def command_epilog(cmd) -> str:
    """The examples of a command (its EXAMPLES, if any), then EPILOG."""
    examples = getattr(cmd, "EXAMPLES", ())
    head = "examples:\n" + "".join(f"  {e}\n" for e in examples) + "\n" if examples else ""
    return head + EPILOG


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
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
        sp = sub.add_parser(
            cmd.NAME,
            help=cmd.HELP,
            description=cmd.DESCRIPTION,
            epilog=command_epilog(cmd),
            formatter_class=HelpFormatter,
        )
        cmd.add_arguments(sp)
        sp.set_defaults(run=cmd.run, json_events=getattr(cmd, "JSON_EVENTS", False))
    return p


def main(argv: Optional[list[str]] = None) -> int:
    """Runs the command. One that an exception ends (--timeout, Ctrl-C, a
    port or bus error) still prints its JSON document with --json (see
    Context.cut_short); bad arguments (exit 2) print none."""
    args = build_parser().parse_args(argv)  # exits 2 on bad arguments
    gateway_client.register_names()  # sniff names and decodes the gateway's codes
    ctx = Context(args)
    try:
        return args.run(ctx)
    except CliError as e:
        ctx.error(str(e))
        return e.exit_code
    except OperationTimeout:
        what = f"timed out after {args.timeout:g} s"
        return ctx.cut_short(OperationTimeout(what), f"{args.command}: {what}", EXIT_FAIL)
    except DanError as e:
        return ctx.cut_short(e, f"{args.command}: {e}", EXIT_FAIL)
    except PortError as e:
        return ctx.cut_short(DanError(str(e)), f"{args.command}: {e}", EXIT_FAIL)
    except KeyboardInterrupt:
        return ctx.cut_short(Stopped("interrupted"), "interrupted", EXIT_INTERRUPTED)
    except BrokenPipeError:
        # stdout closed early (| head): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_FAIL


if __name__ == "__main__":
    sys.exit(main())
