#!/usr/bin/env python3
"""junit_schema_check.py FILE: checks a JUnit XML file against the rules of the Jenkins xUnit
plugin's JUnit schema (junit-10.xsd, the schema Jenkins' xUnit plugin validates against; not
packaged in Debian, so its rules are written out here): the elements each element may hold, the
attributes each may carry, the required ones, and the time format. Prints every violation with
its element's path and exits 1 when there is one; prints the totals and exits 0 otherwise."""
import re
import sys
import xml.etree.ElementTree as ET

# element: (allowed attributes, required attributes, allowed children)
RESULT = ({"type", "message"}, set(), set())
RERUN = ({"type", "message"}, {"type"}, {"stackTrace", "system-out", "system-err"})
RULES = {
    "testsuites": ({"name", "time", "tests", "failures", "errors"}, set(), {"testsuite"}),
    "testsuite": ({"name", "tests", "failures", "errors", "group", "time", "skipped", "timestamp", "hostname", "id",
                   "package", "file", "log", "url"}, {"name", "tests", "failures", "errors"},
                  {"testsuite", "properties", "testcase", "system-out", "system-err"}),
    "testcase": ({"name", "time", "classname", "group"}, {"name"},
                 {"skipped", "error", "failure", "rerunFailure", "rerunError", "flakyFailure", "flakyError", "system-out",
                  "system-err"}),
    "failure": RESULT, "error": RESULT, "skipped": RESULT,
    "rerunFailure": RERUN, "rerunError": RERUN, "flakyFailure": RERUN, "flakyError": RERUN,
    "properties": (set(), set(), {"property"}),
    "property": ({"name", "value"}, {"name", "value"}, set()),
    "system-out": (set(), set(), set()), "system-err": (set(), set(), set()),
    "stackTrace": (set(), set(), set()),
}
TIME = re.compile(r"(([0-9]{0,3},)*[0-9]{3}|[0-9]{0,3})*(\.[0-9]*)?")  # SUREFIRE_TIME
TIMED = {"testsuites", "testsuite"}  # where time is SUREFIRE_TIME (a testcase's is any string)


def check(el, path, problems):
    allowed, required, children = RULES[el.tag]
    for a in el.attrib:
        if a not in allowed:
            problems.append(f"{path}: attribute '{a}' is not allowed on <{el.tag}>")
    for a in required - el.attrib.keys():
        problems.append(f"{path}: <{el.tag}> needs attribute '{a}'")
    if el.tag in TIMED and "time" in el.attrib and not TIME.fullmatch(el.attrib["time"]):
        problems.append(f"{path}: time '{el.attrib['time']}' is not a SUREFIRE_TIME")
    for i, child in enumerate(el):
        where = f"{path}/{child.tag}[{i}]"
        if child.tag not in children or child.tag not in RULES:
            problems.append(f"{where}: <{child.tag}> is not allowed in <{el.tag}>")
            continue
        check(child, where, problems)


def main():
    root = ET.parse(sys.argv[1]).getroot()
    problems = []
    if root.tag not in ("testsuites", "testsuite"):
        problems.append(f"root <{root.tag}> is neither <testsuites> nor <testsuite>")
    else:
        check(root, root.tag, problems)
    for p in problems:
        print(p)
    if problems:
        return 1
    cases = root.findall(".//testcase")
    print(f"valid: {len(cases)} testcases, {len(root.findall('.//failure'))} failures, "
          f"{len(root.findall('.//error'))} errors, {len(root.findall('.//skipped'))} skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
