"""wsnlib._arguments: the number arguments of the command lines."""

import argparse

import pytest

from wsnlib._arguments import positive_number, whole_number


def test_whole_numbers_in_range_are_read_and_the_rest_named_with_the_range():
    assert whole_number(1)("7") == 7 and whole_number(0, 65535)("0") == 0 and whole_number(1, 32)("32") == 32
    for parse, text, said in ((whole_number(1), "0", "'0': needs a whole number >= 1"),
                              (whole_number(1), "2.5", "'2.5': needs a whole number >= 1"),
                              (whole_number(1, 32), "33", "'33': needs a whole number 1-32"),
                              (whole_number(0, 65535), "-1", "'-1': needs a whole number 0-65535")):
        with pytest.raises(argparse.ArgumentTypeError, match=said):
            parse(text)


def test_positive_numbers_are_finite_and_above_zero():
    assert positive_number("0.5") == 0.5 and positive_number("1e3") == 1000.0
    for text in ("0", "-3", "inf", "nan", "x"):
        with pytest.raises(argparse.ArgumentTypeError, match="needs a number > 0"):
            positive_number(text)


def test_the_batch_runner_refuses_bad_numbers_as_usage_errors(capsys):
    from wsnlib.reproduce import main

    for args, said in ((["--jobs", "0"], "argument --jobs: '0': needs a whole number >= 1"),
                       (["--cell-timeout", "inf"], "argument --cell-timeout: 'inf': needs a number > 0")):
        with pytest.raises(SystemExit) as stopped:
            main(args)
        assert stopped.value.code == 2 and said in capsys.readouterr().err
