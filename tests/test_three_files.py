"""serve/three_files.py: three.js for the page, unpacked from the pinned npm tarball."""

from __future__ import annotations

import io
import tarfile

import pytest

from mlct.errors import MlctError
from mlct.serve import three_files
from mlct.serve.site import vendor


def _fake_tarball(folder, files):
    """A three tarball holding `files` (member -> bytes), with the lock file's name."""
    pin = next(p for p in vendor.pins() if p.name == "three")
    path = folder / pin.tarball
    with tarfile.open(path, "w:gz") as archive:
        for member, data in files.items():
            info = tarfile.TarInfo(member)
            info.size = len(data)
            archive.addfile(info, io.BytesIO(data))
    return pin, path


def test_unpacks_the_page_files_in_the_loaders_layout(tmp_path, monkeypatch):
    monkeypatch.setenv("MLCT_WEB_CACHE", str(tmp_path))
    files = {member: member.encode() for member in three_files.FILES}
    pin, _ = _fake_tarball(tmp_path, files)
    monkeypatch.setattr(vendor, "_digest_ok", lambda path, p: True)  # a fake, not npm's
    folder = three_files.three_dir(fetch=False)
    assert folder == tmp_path / f"three-{pin.version}"
    for member, name in three_files.FILES.items():
        assert (folder / name).read_bytes() == member.encode()
    # GLTFLoader imports "../utils/BufferGeometryUtils.js": the layout must keep that path
    assert (folder / "loaders" / ".." / "utils" / "BufferGeometryUtils.js").is_file()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".three-")]  # no staging left
    # a second call reuses the folder without reading the tarball
    (tmp_path / pin.tarball).unlink()
    assert three_files.three_dir(fetch=False) == folder


def test_a_tarball_without_a_file_leaves_nothing_behind(tmp_path, monkeypatch):
    monkeypatch.setenv("MLCT_WEB_CACHE", str(tmp_path))
    files = {member: b"x" for member in list(three_files.FILES)[:-1]}  # no LICENSE
    pin, _ = _fake_tarball(tmp_path, files)
    monkeypatch.setattr(vendor, "_digest_ok", lambda path, p: True)
    with pytest.raises(MlctError, match="has no package/LICENSE"):
        three_files.three_dir(fetch=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == [pin.tarball]


def test_no_fetch_and_no_cache_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("MLCT_WEB_CACHE", str(tmp_path))
    with pytest.raises(MlctError, match="is not in .*npm registry"):
        three_files.three_dir(fetch=False)


def test_a_tarball_that_is_not_the_pinned_one_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("MLCT_WEB_CACHE", str(tmp_path))
    _fake_tarball(tmp_path, {member: b"x" for member in three_files.FILES})
    with pytest.raises(MlctError, match="sha512 differs"):
        three_files.three_dir(fetch=False)
    assert not (tmp_path / "three-0.187.0").exists()


def test_the_server_serves_three_when_cached_and_the_page_without_it(tmp_path, monkeypatch):
    pytest.importorskip("fastapi")
    from fastapi.testclient import TestClient

    import mlct
    from mlct.serve import ServeSettings, create_app

    monkeypatch.setenv("MLCT_WEB_CACHE", str(tmp_path))
    generator = mlct.load()
    with TestClient(create_app(generator, ServeSettings(warmup=False))) as client:
        assert client.get("/static/three/three.module.js").status_code == 404
        assert client.get("/static/body.js").status_code == 200  # the page is still served
        assert "three.module.js" in client.get("/").text
    files = {member: member.encode() for member in three_files.FILES}
    _fake_tarball(tmp_path, files)
    monkeypatch.setattr(vendor, "_digest_ok", lambda path, p: True)
    with TestClient(create_app(generator, ServeSettings(warmup=False))) as client:
        got = client.get("/static/three/loaders/GLTFLoader.js")
        assert got.status_code == 200
        assert got.content == b"package/examples/jsm/loaders/GLTFLoader.js"
        assert client.get("/static/app.js").status_code == 200
