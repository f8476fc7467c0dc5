"""console.deferred_sigint: SIGINT as a request inside the block, the handler restored after."""

import os
import signal
import threading

from cdr_translator.console import deferred_sigint
import pytest


@pytest.fixture(autouse=True)
def python_sigint_handler():
    """Python's own SIGINT handler for the test (a CI job may start with SIGINT ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_a_second_sigint_interrupts_at_once():
    """The first SIGINT sets ``requested``, the second raises KeyboardInterrupt."""
    with deferred_sigint() as interrupt:
        assert not interrupt.requested
        os.kill(os.getpid(), signal.SIGINT)
        assert interrupt.requested
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_outside_the_main_thread_nothing_changes():
    """In a worker thread the handler cannot be set: the block leaves SIGINT as it was."""
    seen = []

    def work():
        with deferred_sigint() as interrupt:
            seen.append((signal.getsignal(signal.SIGINT), interrupt.requested))

    worker = threading.Thread(target=work)
    worker.start()
    worker.join(timeout=10)
    assert seen == [(signal.default_int_handler, False)]


def test_an_ignored_sigint_stays_ignored():
    """A process that ignores SIGINT (a background job) keeps ignoring it in the block."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with deferred_sigint() as interrupt:
        os.kill(os.getpid(), signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN and not interrupt.requested
    assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
