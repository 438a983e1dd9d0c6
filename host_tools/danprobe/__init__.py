"""danprobe: the DAN v1 technician's tool (see host_tools/README.md)."""

__version__ = "0.1.0"
