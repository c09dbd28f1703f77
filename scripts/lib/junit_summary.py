"""Counts the test cases in the JUnit XML files under a directory.

Prints one line per failed case ("FAILED suite.case: message"), then a last
line "PASSED FAILED SKIPPED" (three integers) for scripts/test to read.
A file that cannot be parsed counts as one failed case.
"""
import pathlib
import sys
import xml.etree.ElementTree as ET


def classify(case):
    """'failed', 'skipped' or 'passed' for one <testcase>."""
    if case.find("failure") is not None or case.find("error") is not None:
        return "failed"
    if (case.find("skipped") is not None or case.get("status") == "notrun"
            or case.get("result") == "skipped"):
        return "skipped"
    return "passed"


def is_covered_rostest_wrapper(case, inner_results):
    """rostest writes a wrapper case "test<name>" next to the test node's own
    results in rosunit-<name>.xml; the wrapper only adds information (a crash
    or a timeout) when those results are missing."""
    name = case.get("name") or ""
    return (case.get("classname") == "rostest.runner.RosTest" and name.startswith("test")
            and name[len("test"):] in inner_results)


def main(root):
    counts = {"passed": 0, "failed": 0, "skipped": 0}
    paths = sorted(pathlib.Path(root).rglob("*.xml"))
    inner_results = {p.stem[len("rosunit-"):] for p in paths if p.stem.startswith("rosunit-")}
    for path in paths:
        try:
            cases = ET.parse(path).getroot().iter("testcase")
            for case in cases:
                if is_covered_rostest_wrapper(case, inner_results):
                    continue
                outcome = classify(case)
                counts[outcome] += 1
                if outcome == "failed":
                    bad = case.find("failure")
                    if bad is None:
                        bad = case.find("error")
                    message = " ".join((bad.get("message") or bad.text or "").split())
                    print("FAILED %s.%s: %s (%s)" % (case.get("classname"), case.get("name"),
                                                      message[:300], path.name))
        except ET.ParseError as error:
            counts["failed"] += 1
            print("FAILED %s: unreadable test result (%s)" % (path.name, error))
    print(counts["passed"], counts["failed"], counts["skipped"])


if __name__ == "__main__":
    main(sys.argv[1])
