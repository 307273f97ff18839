"""Job functions for the fan-out tests (a module, so worker processes can import them)."""

import os
import signal
import time
from pathlib import Path


def square(x):
    return x * x


def fail_once(marker, crash=False):
    """Fails (raising, or killing its process) on the first call, succeeds afterwards."""
    path = Path(marker)
    if not path.exists():
        path.write_text("attempted")
        if crash:
            os._exit(3)
        raise RuntimeError("first attempt fails")
    return "second attempt worked"


def always_fails():
    raise ValueError("broken job")


def slow_square(x, seconds):
    time.sleep(seconds)
    return x * x


def crash(how):
    """Dies without a result: ``segfault`` (SIGSEGV) or ``exit`` (``os._exit(7)``)."""
    if how == "segfault":
        os.kill(os.getpid(), signal.SIGSEGV)
    os._exit(7)


def thread_pools():
    """What this worker's thread pools were sized to: ``OMP_NUM_THREADS`` and torch's pool."""
    import torch

    return os.environ.get("OMP_NUM_THREADS"), torch.get_num_threads()
