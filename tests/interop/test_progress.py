"""Progress on a terminal, quiet in CI: `drivetwin scenario` over several files and `drivetwin
scan` draw a progress line on standard error only when it is a terminal and `CI` is not set;
piped (as every other test here runs the CLI) their output is what it was, byte for byte."""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess

from conftest import DRIVETWIN_BIN, REPO_ROOT, run_cli

EXAMPLES = REPO_ROOT / "examples" / "scenarios"
FILES = [str(EXAMPLES / "limit_switch.toml"), str(EXAMPLES / "diagnostic.toml")]


def stderr_on_a_terminal(args: list[str], env: dict[str, str]) -> tuple[int, bytes, bytes]:
    """Runs drivetwin with standard error on a pseudo-terminal (standard output piped):
    the exit code, standard output, and what the terminal received."""
    master, slave = pty.openpty()
    p = subprocess.Popen([str(DRIVETWIN_BIN), *args], stdout=subprocess.PIPE, stderr=slave, env=env)
    os.close(slave)
    seen = b""
    while True:
        ready, _, _ = select.select([master], [], [], 120)
        if not ready:
            break
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the terminal closed: the process ended
            break
        if not chunk:
            break
        seen += chunk
    out = p.stdout.read()
    code = p.wait(timeout=120)
    os.close(master)
    return code, out, seen


def logged(text: str | bytes) -> str:
    """Standard error as the log lines say it, whatever the clock read and however a terminal
    ends its lines."""
    if isinstance(text, bytes):
        text = text.decode().replace("\r\n", "\n")
    return re.sub(r"\d{4}-\d\d-\d\dT[\d:.]+Z", "<time>", text)


def env_without_ci(**extra: str) -> dict[str, str]:
    """A person's terminal: no `CI`, a `TERM` that draws."""
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env["TERM"] = "xterm-256color"
    env.update(extra)
    return env


def test_piped_output_of_several_scenarios_is_each_ones_own_and_stderr_stays_empty():
    one = [run_cli("scenario", f, timeout=120) for f in FILES]
    both = run_cli("scenario", *FILES, timeout=120)
    assert [r.returncode for r in one] == [0, 0] and both.returncode == 0, both.stderr
    assert both.stdout == "".join(r.stdout for r in one)
    # Standard error carries the cells' own log lines (a heartbeat lost at power-on), nothing more.
    assert logged(both.stderr) == "".join(logged(r.stderr) for r in one)
    assert "\r" not in both.stderr and "\x1b[2K" not in both.stderr


def test_a_terminal_sees_progress_and_ci_sees_none():
    code, out, tty = stderr_on_a_terminal(["scenario", *FILES], env_without_ci())
    assert code == 0
    # The bar, drawn, counted to 2/2 and cleared.
    assert b"scenario " in tty and b" 2/2 " in tty and tty.endswith(b"\r\x1b[2K"), tty
    piped = run_cli("scenario", *FILES, timeout=120)
    assert out.decode() == piped.stdout

    code, out_ci, tty_ci = stderr_on_a_terminal(["scenario", *FILES], env_without_ci(CI="true"))
    assert code == 0 and out_ci == out
    assert logged(tty_ci) == logged(piped.stderr), tty_ci  # the log lines alone


def test_scan_on_a_terminal_outside_ci_turns_a_spinner_and_prints_the_same(cmmp):
    args = ["scan", "--socketcand", cmmp.addr, "--timeout-ms", "600"]
    piped = run_cli(*args)
    assert piped.returncode == 0 and piped.stderr == "", piped.stderr  # a scan logs nothing
    assert piped.stdout.startswith("node 1: device type ") and piped.stdout.count("\n") == 1, piped.stdout
    code, out, tty = stderr_on_a_terminal(args, env_without_ci())
    assert code == 0 and out.decode() == piped.stdout
    assert b"nodes answered" in tty, tty
    code, out, tty = stderr_on_a_terminal(args, env_without_ci(CI="1"))
    assert code == 0 and out.decode() == piped.stdout and tty == b"", tty


def test_on_a_terminal_a_log_line_never_shares_its_line_with_the_bar():
    """The cells log while the bar is drawn (a heartbeat lost at power-on in each file): each
    log line starts on a line of its own, the bar cleared before it and drawn again after."""
    files = FILES * 3  # more lines, each logged between two draws of the bar
    code, out, tty = stderr_on_a_terminal(["scenario", *files], env_without_ci())
    assert code == 0
    stamps = [m.start() for m in re.finditer(rb"\d{4}-\d\d-\d\dT[\d:.]+Z", tty)]
    assert stamps, f"the scenarios logged nothing: {tty!r}"
    assert b"scenario " in tty, tty
    for at in stamps:
        line = tty[: at].rsplit(b"\n", 1)[-1]
        # What the terminal still shows before the log line on its line: nothing after the
        # last carriage return or line clear (colour codes aside).
        shown = re.sub(rb"\x1b\[[0-9;]*m", b"", re.split(rb"\r|\x1b\[2K", line)[-1])
        assert shown == b"", f"a log line after {shown!r} on one line: {tty[max(0, at - 120): at + 80]!r}"
    # The log lines are the piped run's, and the bar ends drawn to the end and cleared.
    piped = run_cli("scenario", *files, timeout=120)
    assert out.decode() == piped.stdout
    assert len(stamps) == len(re.findall(r"\d{4}-\d\d-\d\dT[\d:.]+Z", piped.stderr)), piped.stderr
    assert f" {len(files)}/{len(files)} ".encode() in tty and tty.endswith(b"\r\x1b[2K"), tty[-200:]
