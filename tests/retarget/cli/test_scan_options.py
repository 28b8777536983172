"""``retarget scan``: a bad option exits 2 (not 4, which is for a bus or port failure)."""

from __future__ import annotations

import pytest

from retarget.cli import main


@pytest.mark.parametrize("baud", ["12345", "4500000", "0"])
def test_a_baud_no_servo_can_use_exits_2_naming_the_option(capsys, baud):
    code = main(["scan", "--port", "sim://wx250s", "--baud", baud])
    err = capsys.readouterr().err
    assert code == 2
    assert (
        err.startswith("retarget: --baud: Expected a baud rate a servo can use: 9600, 57600, ") and err.count("\n") == 1
    ), err
    assert f"(got {baud})" in err


def test_a_supported_baud_scans(capsys):
    code = main(["scan", "--port", "sim://wx250s", "--baud", "1000000", "--ids", "1-2", "--no-broadcast"])
    assert code == 0 and "2 servo(s) found" in capsys.readouterr().err
