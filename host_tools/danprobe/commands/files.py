"""danprobe files: the gateway's file store (firmware images for DroneCAN
nodes), through FILE_OPEN..FILE_REMOVE."""

import argparse
import os

from danprobe import file_update
from danprobe import gateway_file as F
from danprobe.commands.common import (
    EXIT_INTERRUPTED,
    UsageError,
    format_table,
    gateway_actions,
    gateway_operation,
    gateway_report,
    stop_signals,
)
from danprobe.commands.progress import Progress, rate_text

NAME = "files"
HELP = "CAN gateway: its file store (firmware images): 'files list|put FILE|rm NAME'"
DESCRIPTION = (
    "The gateway's file store, which DroneCAN nodes read firmware images from "
    "(uavcan.protocol.file.Read). 'list' shows the committed files; 'put FILE' uploads one "
    "(FILE_OPEN, FILE_WRITE of 150 bytes each, FILE_COMMIT with its CRC-32), with a progress "
    "line on stderr; 'rm NAME' removes one. A name is 1..32 characters of A-Z a-z 0-9 . _ - "
    "not starting with '.'. An interrupted upload (Ctrl-C, a lost link, a killed danprobe) "
    "stays in the gateway as a partial file: 'put' of the same file again resumes where the "
    "gateway stopped (--restart starts from byte 0). Ctrl-C stops between two transactions "
    "(never in the middle of a frame) and exits 130; the partial upload is kept, not "
    "committed, and no node sees it."
)
EXAMPLES = (
    "danprobe files put --port /dev/ttyUSB0 --configure esc-2.1.bin",
    "danprobe files list --port /dev/ttyUSB0 --baud 115200",
    "danprobe files rm --port /dev/ttyUSB0 --baud 115200 esc-2.0.bin",
)


def store_name(s: str) -> str:
    """An argument type: a file store name."""
    try:
        F.file_name(s)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return s


def add_name_option(g):
    g.add_argument(
        "--name",
        type=store_name,
        metavar="N",
        help="the name in the gateway's store (default: the file's own name)",
    )


def add_arguments(p):
    helps = {
        "list": "the committed files and their sizes",
        "put": "upload a file (resumes an interrupted upload of it)",
        "rm": "remove a file",
    }
    for name, g in gateway_actions(p, "files", helps, DESCRIPTION):
        if name == "put":
            g.add_argument("file", metavar="FILE", help="the file to upload")
            add_name_option(g)
            g.add_argument(
                "--restart",
                action="store_true",
                help="start the upload from byte 0 (default: resume a partial one)",
            )
        if name == "rm":
            g.add_argument("name", type=store_name, metavar="NAME", help="the file to remove")


def read_image(ctx, path: str, name: str = None) -> tuple[bytes, str]:
    """(the file's bytes, its store name); bad input: UsageError (exit 2)."""
    try:
        with open(path, "rb") as f:
            data = f.read(F.SIZE_MAX + 1)
    except OSError as e:
        raise UsageError(f"{ctx.args.command}: {path}: {e.strerror}") from None
    if not data:
        raise UsageError(f"{ctx.args.command}: {path} is empty")
    if len(data) > F.SIZE_MAX:
        raise UsageError(f"{ctx.args.command}: {path} is over 4 GiB")
    name = name or os.path.basename(path)
    try:
        F.file_name(name)
    except ValueError as e:
        raise UsageError(f"{ctx.args.command}: {e}: give --name") from None
    return data, name


def put(ctx, gw, data: bytes, name: str, restart: bool, res: dict) -> file_update.Upload:
    """The upload with its progress line; res["upload"] holds where it got
    (also when it stopped or failed)."""
    stop = stop_signals(ctx)
    bar = []

    def opened(u):
        res["upload"] = u
        if u.resumed_from:
            ctx.progress(f"resuming {name} at byte {u.resumed_from} of {u.size}")
        bar.append(Progress(f"upload {name}", u.size, u.resumed_from, ctx.args.quiet))
        bar[0].update(u.have)

    with stop:
        try:
            u = file_update.upload(
                gw,
                name,
                data,
                restart,
                progress=lambda u: bar[0].update(u.have),
                stop=lambda: stop.stop,
                on_open=opened,
            )
        finally:
            if bar:
                bar[0].end()
    rate = rate_text(u.sent / u.seconds) if u.seconds > 0 else "-"
    ctx.progress(
        f"committed {name}: {u.size} bytes, CRC-32 0x{u.crc:08x}, {u.sent} sent in "
        f"{u.seconds:.1f} s ({rate})"
    )
    return u


def finish(ctx, m, failure, ms, fields, human) -> int:
    """gateway_report(), with exit 130 and what the gateway keeps after Ctrl-C."""
    up = fields.get("upload")
    if isinstance(up, file_update.Upload):
        fields["upload"] = up.as_dict()
    rc = gateway_report(ctx, m, failure, ms, fields, human)
    if isinstance(failure, file_update.Stopped):
        if isinstance(up, file_update.Upload) and not up.committed:
            ctx.error(
                f"interrupted: the gateway keeps {up.have} of {up.size} bytes of "
                f"{up.name.decode()} (not committed); the same command resumes there"
            )
        return EXIT_INTERRUPTED
    return rc


def run(ctx) -> int:
    a = ctx.args
    res = {"action": a.files_command}
    if a.files_command == "put":
        data, name = read_image(ctx, a.file, a.name)
        res["name"] = name

    def op(m, gw):
        if a.files_command == "list":
            res["files"] = file_update.file_list(gw)
        elif a.files_command == "put":
            put(ctx, gw, data, name, a.restart, res)
        else:
            r = file_update.file_remove(gw, a.name)
            res["removed"] = a.name
            if r != F.FILE_OK:
                raise file_update.FileError(f"FILE_REMOVE {a.name}", r)

    m, failure, ms = gateway_operation(ctx, op)
    files = res.pop("files", None)
    if files is not None:
        res["files"] = [f.as_dict() for f in files]

    def human():
        if files is not None:
            print(f"files: {len(files)} file(s), {sum(f.size for f in files)} bytes")
            if files:
                print(
                    format_table([("name", "size")] + [(f.name_text, str(f.size)) for f in files])
                )
        elif a.files_command == "put":
            u = res["upload"]
            print(f"files put: {name}: {u['size']} bytes, CRC-32 {u['crc32']} ({ms:.0f} ms)")
        else:
            print(f"files rm: {a.name} removed")

    return finish(ctx, m, failure, ms, res, human)
