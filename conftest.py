"""Suite-wide pytest rule: under ``CECO_REQUIRE_EXTRAS=1`` (set by .ci/run) nothing may skip.

On a developer's machine a test whose requirement is missing skips and says why (the stack tests without
the sourced ROS 2 workspace, the extras without requirements/analysis.txt, the keystore test without
openssl). CI installs all of it, so there a skip can only mean something broke (rclpy that no longer
imports would otherwise skip every stack test and leave CI green): the session fails and names each
skipped test with its reason.
"""

import os

REQUIRE_ENV = "CECO_REQUIRE_EXTRAS"


def skipped_reports(terminalreporter) -> list:
    """The skip reports of the session (collection and test skips alike)."""
    return list(terminalreporter.stats.get("skipped", []))


def pytest_sessionfinish(session, exitstatus):
    """Under the CI switch, fail a session that skipped anything and list each skip with its reason."""
    if os.environ.get(REQUIRE_ENV) != "1":
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = skipped_reports(reporter) if reporter is not None else []
    if not skipped:
        return
    lines = [f"{len(skipped)} skipped with {REQUIRE_ENV}=1 (CI installs every requirement; a skip here is a failure):"]
    for rep in skipped:
        reason = rep.longrepr[2] if isinstance(rep.longrepr, tuple) else str(rep.longrepr)
        lines.append(f"  {rep.nodeid}: {reason}")
    if reporter is not None:
        reporter.write_line("\n".join(lines), red=True)
    if exitstatus == 0:
        session.exitstatus = 1
