"""Every picture of the manual (README.md, docs/) comes from scripts/make_pictures.py, and none is stale.

docs/images/senses_light_seeker.png showed a contact and a path along the bottom wall that today's runs do not
make, and the README's text about it was as old. The script remakes every picture in a scratch folder and compares
each with the committed one, and the manual's figures about them with the runs' (see its docstring).
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from manual_pages import manual_text

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / 'scripts' / 'make_pictures.py'


def test_every_picture_of_the_manual_is_made_by_the_script():
    """No picture in the manual that the script does not make, and no picture file nobody shows."""
    shown = set(re.findall(r'images/([\w.-]+)\.png', manual_text()))
    made = set(re.findall(r"Picture\('(\w+)'", SCRIPT.read_text()))
    files = {path.stem for path in (ROOT / 'docs' / 'images').glob('*.png')}
    assert shown == made == files, (shown ^ made, made ^ files)


@pytest.mark.slow   # remakes every picture: 40 s of both cores
def test_the_pictures_and_the_readmes_figures_are_those_the_commands_make_today():
    run = subprocess.run([sys.executable, str(SCRIPT), '--check'], capture_output=True, text=True, timeout=3600)
    assert run.returncode == 0, run.stdout + run.stderr
