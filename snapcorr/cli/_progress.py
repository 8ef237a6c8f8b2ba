"""Progress bars (tqdm, on stderr) over the long steps of a command."""

from __future__ import annotations

import sys

#: Progress bars: None on a terminal only (the default), False never (``--quiet``), True
#: always, from the start (``--progress``); set by :func:`main` for the command it runs.
_SHOW_PROGRESS = None


def _progress_bar(desc, unit, total, **options):
    """A tqdm bar on stderr as ``--quiet`` and ``--progress`` say: by default shown after a
    second of work, on a terminal only (not in logs or pipes)."""
    from tqdm import tqdm

    asked = _SHOW_PROGRESS is True
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                delay=0 if asked else _StageBar.DELAY_S, leave=asked, dynamic_ncols=True,
                disable=None if _SHOW_PROGRESS is None else not _SHOW_PROGRESS,
                mininterval=0.1 if sys.stderr.isatty() else 1.0, **options)


class _Ticking:
    """Redraws a bar every second while a long step gives it nothing to count, so its
    elapsed time shows that the work goes on (after the bar's delay, as tqdm would)."""

    def __init__(self, bar, every_s=1.0):
        import threading

        self.bar, self.every_s = bar, every_s
        self.stop = threading.Event()
        self.thread = None
        if not bar.disable:
            self.thread = threading.Thread(target=self._run, name="snapcorr-progress",
                                           daemon=True)
            self.thread.start()

    def _run(self):
        import time

        while not self.stop.wait(self.every_s):
            if time.time() - self.bar.start_t >= self.bar.delay:
                self.bar.refresh()

    def close(self):
        self.stop.set()
        if self.thread is not None:
            self.thread.join()


class _StageBar:
    """One labelled progress bar (tqdm, on stderr) over every dask computation of a stage.

    With ``frames``, a stream's: frames done (each computation's share of its tasks done, in
    frames), frames per second and the time left, bar by bar for each writing pass."""

    #: Seconds of work before the bar shows (short stages print nothing).
    DELAY_S = 1.0

    def __init__(self, desc, frames=None, count=True):
        self.desc, self.frames, self.count = desc, frames, count

    def __enter__(self):
        from dask.callbacks import Callback

        frames, desc = self.frames, self.desc
        # work that gives nothing to count shows the time it has taken
        self.bar = bar = _progress_bar(desc, "frame" if frames else "block", frames or 0,
                                       **({} if self.count else
                                          {"bar_format": "{desc} ({elapsed})"}))
        counts = {"passes": 0, "done": 0, "tasks": 0}
        stage = self

        class _Count(Callback):
            def _start_state(self, dsk, state):
                if not stage.count:
                    return
                tasks = len(state["ready"]) + len(state["waiting"])
                counts["passes"] += 1
                if frames is None:
                    bar.total += tasks
                    return
                counts.update(done=0, tasks=max(tasks, 1))
                if counts["passes"] > 1:  # each writing pass goes through every frame
                    bar.reset(total=frames)
                    bar.set_description(f"{desc} (pass {counts['passes']})", refresh=False)

            def _posttask(self, key, result, dsk, state, worker_id):
                if not stage.count:
                    return
                if frames is None:
                    bar.update(1)
                    return
                counts["done"] += 1
                bar.update(frames * counts["done"] // counts["tasks"] - bar.n)

            def _finish(self, dsk, state, errored):
                bar.refresh()  # each pass's end is seen (a log keeps it)

        self.callback = _Count()
        self.callback.__enter__()
        self.ticking = _Ticking(bar)
        return self

    def __exit__(self, *exc):
        self.ticking.close()
        self.callback.__exit__(*exc)
        self.bar.close()


class _StepBar:
    """A progress bar (tqdm, on stderr, on a terminal only) over the named steps of a long
    computation: ``step(description)`` is called before each one."""

    def __init__(self, desc, total=None):
        self.desc, self.total = desc, total

    def __enter__(self):
        self.bar = _progress_bar(self.desc, "step", self.total)
        self.started = False
        self.ticking = _Ticking(self.bar)
        return self

    def step(self, what=""):
        if self.started:
            self.bar.update(1)
        self.started = True
        self.bar.set_postfix_str(what, refresh=True)

    def skip(self, n):
        """``n`` steps of the total that will not be taken (work found not to apply): the bar
        still ends at its total."""
        if self.bar.total is not None:
            self.bar.total = max(self.bar.total - n, self.bar.n)
            self.bar.refresh()

    def __exit__(self, exc_type, *exc):
        if self.started and exc_type is None:  # the last step is done too: total of total
            self.bar.update(1)
        self.ticking.close()
        self.bar.close()

