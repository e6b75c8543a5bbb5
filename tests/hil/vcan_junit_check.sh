#!/usr/bin/env bash
# Runs the vcan suite (the command after --, normally run-on-vcan.sh ... test_hil_vcan) and then
# reads the JUnit XML its hybrid-rig test printed between the HIL-JUNIT markers with a real
# consumer, Debian's python3-junitparser (the VM has no Python): the counts must be those the
# test announced from run.json, and the check set to fail must be a <failure>.
#   vcan_junit_check.sh -- COMMAND [ARGS...]
set -uo pipefail
[[ "${1:-}" == "--" ]] && shift
log=$(mktemp)
trap 'rm -f "$log" "$log.xml"' EXIT
"$@" 2>&1 | tee "$log"
rc=${PIPESTATUS[0]}
((rc == 0)) || exit "$rc"
# The block as printed (the VM's serial console may add carriage returns).
tr -d '\r' <"$log" | sed -n '/^HIL-JUNIT-BEGIN /,/^HIL-JUNIT-END$/p' >"$log.xml"
header=$(head -1 "$log.xml")
if [[ -z "$header" ]]; then
  echo "vcan_junit_check: no HIL-JUNIT block in the suite's output (was the hybrid-rig test filtered out?)" >&2
  exit 1
fi
sed -i '1d;$d' "$log.xml"
/usr/bin/python3 - "$log.xml" "$header" <<'PY'
import sys
from junitparser import JUnitXml, Failure, Skipped
want = dict(kv.split("=") for kv in sys.argv[2].split()[1:])
xml = JUnitXml.fromfile(sys.argv[1])
cases = [c for s in xml for c in s]
failures = [c for c in cases if any(isinstance(r, Failure) for r in c.result)]
skipped = [c for c in cases if any(isinstance(r, Skipped) for r in c.result)]
got = {"tests": len(cases), "failures": len(failures), "skipped": len(skipped)}
print(f"vcan_junit_check: junitparser reads {got} (run.json: tests={want['tests']} failures={want['failures']} "
      f"skipped={want['skipped']}); failing: {[c.name for c in failures]}")
ok = all(got[k] == int(want[k]) for k in got) and want["failing"] in [c.name for c in failures]
sys.exit(0 if ok else 1)
PY
