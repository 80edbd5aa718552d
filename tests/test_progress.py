"""Progress through :mod:`logging` (issue 21 item 6): the handlers of the CLI and the API
(:func:`copdea_fem.progress.progress_to`), quiet sweep points, prefixed sector lines."""

from __future__ import annotations

import logging
import threading

from copdea_fem.cli import main
from copdea_fem.progress import carried, progress_to, quiet_progress, tagged, tagging

LOGGER = logging.getLogger("copdea_fem.some.module")


def test_progress_to_forwards_the_package_records_and_leaves_logging_as_it_was():
    root = logging.getLogger("copdea_fem")
    level, handlers = root.level, list(root.handlers)
    lines = []
    with progress_to(lines.append, only_info=True):
        LOGGER.info("step %d", 1)
        LOGGER.warning("a warning")             # not a progress line
        logging.getLogger("elsewhere").info("not ours")
    LOGGER.info("after")
    assert lines == ["step 1"]
    assert root.level == level and root.handlers == handlers


def test_quiet_progress_hides_steps_not_warnings_and_follows_into_threads():
    lines = []
    with progress_to(lines.append):
        with quiet_progress(), tagging("odd-even: "):
            LOGGER.info("hidden")
            LOGGER.warning(tagged("shown"))
            context = carried()

            def worker():
                with context():
                    LOGGER.info("hidden in a thread")
                    LOGGER.warning(tagged("shown in a thread"))
            thread = threading.Thread(target=worker)
            thread.start()
            thread.join()
        LOGGER.info(tagged("shown again"))
    assert lines == ["odd-even: shown", "odd-even: shown in a thread", "shown again"]


def test_two_runs_in_two_threads_each_see_only_their_own_lines():
    """Two API calls in one process (two threads, both blocks open at once, closed out
    of order): each sink gets its own thread's lines only, and the logger's level is
    the one found before the first block once both are closed."""
    root = logging.getLogger("copdea_fem")
    level = root.level
    root.setLevel(logging.WARNING)
    both_open, first_closed = threading.Barrier(2), threading.Event()
    lines = {"a": [], "b": []}

    def run(name):
        with progress_to(lines[name].append):
            both_open.wait(timeout=10)
            LOGGER.info("step of %s", name)
            if name == "b":
                first_closed.wait(timeout=10)       # b closes after a
                LOGGER.info("b alone")
        if name == "a":
            first_closed.set()
    try:
        threads = [threading.Thread(target=run, args=(name,)) for name in lines]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert lines == {"a": ["step of a"], "b": ["step of b", "b alone"]}
        assert root.level == logging.WARNING and root.handlers == []
    finally:
        root.setLevel(level)


def test_the_cli_prints_the_folder_messages_and_removes_its_handler(tmp_path, capsys,
                                                                   monkeypatch):
    """A leftover of an interrupted run is reported on stderr, also by a command without
    --quiet; the CLI's handler is gone after the command."""
    monkeypatch.chdir(tmp_path)
    study = tmp_path / "study.yaml"
    study.write_text("name: s\n")
    leftover = tmp_path / ".out.staging-0123abcd"
    leftover.mkdir()
    main(["spectrum", str(study), "--out", str(tmp_path / "out")])
    assert f"removed {leftover.name}, an unfinished result an interrupted run left" in \
        capsys.readouterr().err.splitlines()
    assert logging.getLogger("copdea_fem").handlers == []
