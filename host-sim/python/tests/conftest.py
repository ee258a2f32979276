"""Fixtures: a fresh simulated drive (``host-sim drive serve --pace fast --commissioned``)
per test, so no test sees another's state."""

import pytest

import servo_drive as sd


@pytest.fixture
def sim():
    with sd.SimulatedDrive() as s:
        yield s


@pytest.fixture
def drive(sim):
    with sim.connect() as d:
        yield d


@pytest.fixture
def running(drive):
    drive.enable()
    return drive
