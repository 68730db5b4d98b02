"""API keys: owner-only files or the environment; never shown."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from flowtwin.control.transports.credentials import ApiKey, load_api_key
from flowtwin.errors import ProfileError

SECRET = "S3CRET-KEY-0123456789"


def _key_file(tmp_path: Path, mode: int, text: str = SECRET + "\n") -> Path:
    p = tmp_path / "key"
    p.write_text(text, encoding="utf-8")
    p.chmod(mode)
    return p


def test_file_with_0600_is_read(tmp_path: Path) -> None:
    key = load_api_key(file=_key_file(tmp_path, 0o600))
    assert key is not None and key.reveal() == SECRET


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o660, 0o666])
def test_file_readable_by_others_is_refused(tmp_path: Path, mode: int) -> None:
    with pytest.raises(ProfileError, match="accessible by group or others") as exc:
        load_api_key(file=_key_file(tmp_path, mode))
    assert "chmod 600" in str(exc.value) and SECRET not in str(exc.value)


def test_missing_empty_and_directory(tmp_path: Path) -> None:
    with pytest.raises(ProfileError, match="not found"):
        load_api_key(file=tmp_path / "nope")
    with pytest.raises(ProfileError, match="empty"):
        load_api_key(file=_key_file(tmp_path, 0o600, "\n"))
    d = tmp_path / "dir"
    d.mkdir(mode=0o700)
    with pytest.raises(ProfileError, match="not a regular file"):
        load_api_key(file=d)


def test_symlink_refused(tmp_path: Path) -> None:
    target = _key_file(tmp_path, 0o600)
    link = tmp_path / "link"
    os.symlink(target, link)
    with pytest.raises(ProfileError, match="cannot open"):
        load_api_key(file=link)


def test_environment() -> None:
    assert load_api_key(env="MY_KEY", environ={"MY_KEY": f" {SECRET} "}) == \
        ApiKey(SECRET, origin="x")
    assert load_api_key(env="MY_KEY", environ={}) is None
    key = load_api_key(environ={"FLOWTWIN_API_KEY": SECRET})
    assert key is not None and key.reveal() == SECRET


def test_key_never_shown() -> None:
    key = ApiKey(SECRET, origin="test")
    assert SECRET not in repr(key) and SECRET not in str(key) and SECRET not in f"{key}"
    assert SECRET not in repr({"k": key}) and SECRET not in repr([key])
    import pickle
    with pytest.raises(TypeError):
        pickle.dumps(key)
