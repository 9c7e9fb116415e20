"""Test tools, not part of the package: fault injection and the reliability harness.

* :mod:`tests.tools.fault_harness`: the command line run in a fresh process under a probe,
  read-only folders and full disks (tmpfs mounts as root), a workspace with its own cache;
* :mod:`tests.tools.faults`: the bad-input and fault tables built on it;
* :mod:`tests.tools.reliability`: the reliability study that writes docs/reliability.md.

Import them as ``tests.tools.<module>``: the checkout's root must be on ``sys.path``
(``tests/conftest.py`` puts it there for the test session; ``python -m tests.tools.reliability``
run from the root has it). Run from the checkout's root:

    .venv/bin/python -m tests.tools.reliability --out out/reliability --doc docs/reliability.md
    .venv/bin/python -m tests.tools.faults
"""
