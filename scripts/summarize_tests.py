#!/usr/bin/env python3
"""Summarises catkin's JUnit XML test results: failures and skips with their messages, then the
closing line 'N passed, N failed, N skipped'. Exit status 1 when anything failed or nothing ran."""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main(results_dir):
    passed, failed, skipped = 0, 0, 0
    lines = []
    files = sorted(glob.glob(os.path.join(results_dir, "**", "*.xml"), recursive=True))
    for path in files:
        name = os.path.basename(path)
        # rostest-*.xml wraps a whole .test file in one case; the test node's own cases are in
        # rosunit-*.xml. The wrapper counts only when it failed (e.g. the node crashed before
        # writing its results).
        wrapper = name.startswith("rostest-")
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as error:
            failed += 1
            lines.append("FAILED  %s: unreadable result file (%s)" % (name, error))
            continue
        for case in root.iter("testcase"):
            label = "%s.%s" % (case.get("classname", name), case.get("name", "?"))
            failure = case.find("failure")
            if failure is None:
                failure = case.find("error")
            skip = case.find("skipped")
            if wrapper and failure is None:
                continue
            if failure is not None:
                failed += 1
                message = (failure.get("message") or failure.text or "").strip().splitlines()
                lines.append("FAILED  %s: %s" % (label, " | ".join(message[:6])))
            elif skip is not None or case.get("result") == "skipped" or case.get("status") == "notrun":
                skipped += 1
                message = (skip.get("message") if skip is not None else None) or (
                    skip.text if skip is not None and skip.text else "")
                # gtest puts "file:line" on the first line and the reason after it.
                reason = message.strip().splitlines()[-1] if message.strip() else "(no reason given)"
                lines.append("SKIPPED %s: %s" % (label, reason))
            else:
                passed += 1
    for line in lines:
        print(line)
    print("%d passed, %d failed, %d skipped" % (passed, failed, skipped))
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
