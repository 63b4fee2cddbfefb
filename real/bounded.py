"""PortAudio calls that may block for as long as the sound server does not answer, run so
that the caller's thread returns in bounded time.

A stream of a stalled or vanished server blocks ``stop_stream``, ``close``, PortAudio's
initialization and ``Pa_Terminate`` until the server answers again (a PulseAudio server held
with ``SIGSTOP`` left ``PyAudioRig.record`` blocked in ``terminate()`` for as long as it was
stopped). Such calls run here on a daemon thread each, strictly one after another in the
order they were submitted (PortAudio is not meant to be used from two threads at once); the
caller waits at most its timeout. A call that is given up on keeps running and finishes when
the server answers; until it has, :func:`wait_until_idle` tells a new session so, instead of
letting it block behind it.
"""

from __future__ import annotations

import threading
from typing import Any, Callable

_lock = threading.Lock()
_last: _Call | None = None


class _Call:
    def __init__(self, fn: Callable[[], Any], what: str, previous: _Call | None,
                 on_late_result: Callable[[Any], None] | None) -> None:
        self.fn, self.what, self.previous, self.on_late_result = fn, what, previous, on_late_result
        self.done = threading.Event()
        self.abandoned = False
        self.result: Any = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name=f"aas-portaudio: {what}", daemon=True)

    def _run(self) -> None:
        if self.previous is not None:
            self.previous.done.wait()  # strictly after the earlier call, however long it takes
        try:
            self.result = self.fn()
        except BaseException as exc:  # handed to the caller (or dropped if it gave up)
            self.error = exc
        finally:
            self.previous = None  # nothing keeps a chain of finished calls alive
            with _lock:
                late = self.abandoned
                if not late:
                    self.done.set()  # under the lock: the caller either sees it or gave up
        if late:
            # The clean-up is a PortAudio call too: the next call starts after it.
            try:
                if self.error is None and self.on_late_result is not None:
                    self.on_late_result(self.result)
            except Exception:  # nobody waits for this clean-up any more
                pass
            finally:
                self.done.set()


def call_bounded(fn: Callable[[], Any], timeout_s: float, what: str, *,
                 on_late_result: Callable[[Any], None] | None = None) -> tuple[bool, Any]:
    """Run ``fn`` after every earlier call; wait at most ``timeout_s`` seconds.

    Returns ``(True, result)`` (re-raising what ``fn`` raised) or ``(False, None)`` if it had
    not finished in time (or the wait was interrupted, e.g. by Ctrl-C, which is re-raised);
    it then finishes on its own, and ``on_late_result(result)`` cleans up what it produced
    (e.g. terminates a PortAudio session nobody will use). ``what`` says what it does ("closing
    the streams"), for :func:`pending`.
    """
    global _last
    with _lock:
        call = _Call(fn, what, _last, on_late_result)
        _last = call
    call.thread.start()
    try:
        finished = call.done.wait(timeout_s)
    except BaseException:
        finished = False
        raise
    finally:
        if not finished:
            with _lock:
                call.abandoned = not call.done.is_set()
    if call.abandoned:
        return False, None
    if call.error is not None:
        raise call.error
    return True, call.result


def pending() -> str | None:
    """What an unfinished earlier call is doing, or None (calls finish in order, so the
    last one submitted is the one to ask)."""
    with _lock:
        last = _last
    return None if last is None or last.done.is_set() else last.what


def wait_until_idle(timeout_s: float) -> str | None:
    """Wait up to ``timeout_s`` for earlier calls to finish; returns what still blocks, or None."""
    with _lock:
        last = _last
    if last is not None:
        last.done.wait(timeout_s)
    return pending()
