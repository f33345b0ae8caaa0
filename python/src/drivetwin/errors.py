"""The exceptions of the package: one base class, so a test can catch everything drivetwin
raises with one `except drivetwin.DrivetwinError`."""

from __future__ import annotations

from typing import Any, Optional


class DrivetwinError(Exception):
    """Anything that went wrong with a cell or its API."""


class BinaryNotFound(DrivetwinError):
    """No `drivetwin` binary: not in the wheel's scripts folder, not on PATH, no DRIVETWIN_BIN."""


class CellStartError(DrivetwinError):
    """`drivetwin run` ended, or did not say it was running in time; `stderr` is what it said."""

    def __init__(self, message: str, stderr: str = "", stdout: str = ""):
        self.stderr = stderr
        self.stdout = stdout
        detail = stderr.strip() or stdout.strip()
        super().__init__(f"{message}\n{detail}" if detail else message)


class CellDied(DrivetwinError):
    """The cell's process ended while the cell was in use, or did not stop cleanly."""

    def __init__(self, message: str, returncode: Optional[int], stderr: str = ""):
        self.returncode = returncode
        self.stderr = stderr
        tail = stderr.strip()[-4000:]
        super().__init__(f"{message}\n{tail}" if tail else message)


class ApiError(DrivetwinError):
    """The console's REST API answered with an error (the body's `error`, and for a refused SDO
    access its abort code and the manual's reason)."""

    def __init__(self, status: int, method: str, path: str, body: Any):
        self.status = status
        self.method = method
        self.path = path
        self.body = body
        body_dict = body if isinstance(body, dict) else {}
        self.error: str = str(body_dict.get("error", body))
        self.abort_code: Optional[str] = body_dict.get("abort_code")
        self.abort_text: Optional[str] = body_dict.get("abort_text")
        self.reason: Optional[dict] = body_dict.get("reason")
        message = f"{method} {path}: HTTP {status}: {self.error}"
        if self.abort_code and self.abort_code not in self.error:
            message += f" (SDO abort {self.abort_code}: {self.abort_text})"
        super().__init__(message)


class NotFound(ApiError):
    """HTTP 404: no such drive, object, bus, fault, scenario or diagnostic message."""


class Conflict(ApiError):
    """HTTP 409: the drive refused in its present state (an SDO abort, device control held, …)."""


class ApiTimeout(DrivetwinError):
    """The console did not answer in time, or a wait on it (a scenario run) ran out."""
