"""danprobe with one fault injected where no bus can put it on cue:
`python danprobe_faults.py FAULT danprobe-arguments...` (bus_util's
danprobe_with_fault() runs it). The faults:

  arm-answer-lost  every ARM but a disarm reaches the gateway, and then its
                   answer is lost (DanTimeout, as after all the retries)
  recv-fails       the first CAN_RECV never answers (DanTimeout)
  recv-sigint      Ctrl-C (SIGINT to ourselves) during the first CAN_RECV
"""

import os
import signal
import sys

from danprobe import cli
from danprobe.gateway_client import GatewayClient
from danprobe.master import DanTimeout


def arm_answer_lost():
    real = GatewayClient.arm

    def arm(self, status=255):
        flags = real(self, status)
        if status == 0:
            return flags
        raise DanTimeout("ARM: the answer was lost (injected)")

    GatewayClient.arm = arm


def first_can_recv(action):
    real = GatewayClient.can_recv
    calls = []

    def can_recv(self, *args, **kw):
        calls.append(1)
        if len(calls) == 1:
            action()
        return real(self, *args, **kw)

    GatewayClient.can_recv = can_recv


def recv_fails():
    def fail():
        raise DanTimeout("CAN_RECV: no answer (injected)")

    first_can_recv(fail)


def recv_sigint():
    first_can_recv(lambda: os.kill(os.getpid(), signal.SIGINT))


FAULTS = {"arm-answer-lost": arm_answer_lost, "recv-fails": recv_fails, "recv-sigint": recv_sigint}

if __name__ == "__main__":
    FAULTS[sys.argv[1]]()
    sys.exit(cli.main(sys.argv[2:]))
