"""environment.native.held_stderr: what native code writes on descriptor 2 while a file is read
goes to the debug log, not to the terminal (a corrupt USD crate made USD's C++ code print
'failed call to posix_madvise(...)' above the one error line); the descriptor is restored
however the block ends."""

from __future__ import annotations

import logging
import os

import pytest

from baker.environment.native import held_stderr


def test_native_writes_are_held_and_logged(capfd, caplog):
    with caplog.at_level(logging.DEBUG, logger="baker.environment.native"):
        with held_stderr("level.usdc"):
            os.write(2, b"failed call to posix_madvise(...)\n")
    assert capfd.readouterr().err == ""
    assert "posix_madvise" in caplog.text and "level.usdc" in caplog.text
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"


def test_the_descriptor_is_restored_when_the_block_raises(capfd):
    with pytest.raises(ValueError):
        with held_stderr("x"):
            os.write(2, b"held\n")
            raise ValueError("refused")
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"
