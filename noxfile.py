"""Test the declared Python range (requires-python >= 3.10) in fresh virtual environments.

    nox                       # every Python found on this machine, 3.10 to 3.13 (missing ones are skipped)
    nox -s tests-3.10         # one of them
    nox -s tests-3.12 -- tests/firmware_model -x   # extra arguments go to pytest

With pyenv, make the versions visible first, e.g. ``PYENV_VERSION=3.11.7:3.10.13:3.12.1:3.13.0 nox``.
Each session installs the package with its test extra and runs the README's test command (without the slow VM test).
"""

import nox

nox.options.error_on_missing_interpreters = False
nox.options.reuse_existing_virtualenvs = True


@nox.session(python=["3.10", "3.11", "3.12", "3.13"])
def tests(session):
    session.install("-e", ".[test]")
    args = session.posargs or ["-q", "-m", "not vcan", "-p", "no:cacheprovider"]
    session.run("python", "-m", "pytest", *args, env={"OPENBLAS_NUM_THREADS": "1"})
