"""prisma-doctor's lines: each check's `CheckResult`, printed as `OK <check>: <found>` or `FAIL
<check>: <what is wrong> -> <how to fix it>` (WARN and SKIP besides: doctor_checks.py says when)."""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

OK_, WARN_, FAIL_, SKIP_ = "OK", "WARN", "FAIL", "SKIP"


@dataclass(frozen=True)
class CheckResult:
    name: str
    ok: bool
    found: str  # what was found; for a failure, what is wrong
    fix: str = ""  # how to fix it (failures and warnings)
    level: str = ""  # OK, WARN, FAIL or SKIP; "" = OK or FAIL from `ok`

    @property
    def status(self) -> str:
        return self.level or (OK_ if self.ok else FAIL_)

    def line(self) -> str:
        text = f"{self.status} {self.name}: {self.found}"
        return f"{text} -> {self.fix}" if self.fix else text


def passed(name: str, found: str) -> CheckResult:
    return CheckResult(name, True, found)


def failed(name: str, found: str, fix: str) -> CheckResult:
    return CheckResult(name, False, found, fix)


def warned(name: str, found: str, fix: str) -> CheckResult:
    return CheckResult(name, True, found, fix, WARN_)


def skipped(name: str, why: str) -> CheckResult:
    return CheckResult(name, True, f"not checked: {why}", "", SKIP_)



def exit_status(results: Iterable[CheckResult]) -> int:
    return 1 if any(r.status == FAIL_ for r in results) else 0
