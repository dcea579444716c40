"""tumble.signals: the signals that end a command, and handlers set over them for a while."""

from __future__ import annotations

import signal

from tumble import signals


def test_the_ending_signals_are_ctrl_c_kill_and_hang_up():
    assert signals.ENDING[0] == signal.SIGINT and signal.SIGTERM in signals.TERMINATING
    if hasattr(signal, "SIGHUP"):
        assert signals.TERMINATING == (signal.SIGTERM, signal.SIGHUP)


def test_replace_leaves_an_ignored_signal_ignored_and_restore_puts_back_the_rest():
    """Under nohup SIGHUP is ignored and must stay so; the handlers replaced come back as they were."""

    def before(signum, frame):
        pass

    def handler(signum, frame):
        pass

    saved = {n: signal.getsignal(n) for n in (signal.SIGUSR1, signal.SIGUSR2)}
    try:
        signal.signal(signal.SIGUSR1, signal.SIG_IGN)
        signal.signal(signal.SIGUSR2, before)
        previous = signals.replace([signal.SIGUSR1, signal.SIGUSR2, signal.SIGUSR2], handler)
        assert previous == {signal.SIGUSR2: before}
        assert signal.getsignal(signal.SIGUSR1) is signal.SIG_IGN and signal.getsignal(signal.SIGUSR2) is handler
        signals.restore(previous)
        assert signal.getsignal(signal.SIGUSR2) is before
    finally:
        for number, kept in saved.items():
            signal.signal(number, kept)
