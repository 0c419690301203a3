"""wsnlib._user_warnings: a warning names the user's call, at any depth of the library."""

import warnings

from wsnlib._user_warnings import PACKAGE_DIR, warn_user


def _run_as(filename: str, source: str, namespace: dict) -> None:
    exec(compile(source, filename, "exec"), namespace)


def test_the_warning_names_the_first_frame_outside_the_package():
    library = f"{PACKAGE_DIR}/deep.py"  # two frames that count as the package's
    namespace = {"warn_user": warn_user}
    _run_as(library, "def inner():\n    warn_user('inner')\n\ndef outer():\n    inner()\n", namespace)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        namespace["outer"]()  # this line: the user's call
    assert [(w.filename, str(w.message)) for w in caught] == [(__file__, "inner")]


def test_from_a_command_line_of_the_package_the_warning_names_its_entry_point():
    """``python -m wsnlib…``: the frames above the package are the interpreter's frozen ``runpy``,
    which no one can read; the package's outermost frame (its ``__main__``) is named instead."""
    namespace = {"warn_user": warn_user}
    _run_as(f"{PACKAGE_DIR}/deep.py", "def inner():\n    warn_user('from the command line')\n", namespace)
    _run_as(f"{PACKAGE_DIR}/__main__.py", "def main():\n    inner()\n", namespace)
    _run_as("<frozen runpy>", "def run_module():\n    main()\n", namespace)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        namespace["run_module"]()
    assert [(w.filename, w.lineno) for w in caught] == [(f"{PACKAGE_DIR}/__main__.py", 2)]
