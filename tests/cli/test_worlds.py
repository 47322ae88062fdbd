"""``nbv-gym worlds`` as a user runs it: exit codes, messages and files."""

from __future__ import annotations

from tests.helpers import run_cli


def test_worlds_list_names_the_twelve_worlds():
    result = run_cli("worlds", "list")
    names = [line.split()[0] for line in result.stdout.splitlines()]
    assert result.returncode == 0 and len(names) == 12 and "pp2-helicoids" in names


def test_unknown_world_exits_nonzero_listing_valid_ones():
    result = run_cli("worlds", "preview", "pp4-trees")
    assert result.returncode == 2
    assert "Unknown world 'pp4-trees'" in result.stderr and "pp1-cuboids" in result.stderr
    assert "Traceback" not in result.stderr


def test_malformed_spec_file_exits_nonzero_naming_the_field(tmp_path):
    spec = tmp_path / "bad.toml"
    spec.write_text(
        'name = "bad"\n[placement]\nseed = 1\nradius = 3\n[assets]\nmix = {trees = 1}\n'
    )
    result = run_cli("worlds", "build", str(spec))
    assert result.returncode == 2 and "Unknown key placement.radius" in result.stderr


def test_preview_writes_a_png(tmp_path):
    out = tmp_path / "world.png"
    result = run_cli("worlds", "preview", "pp1-cuboids", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
