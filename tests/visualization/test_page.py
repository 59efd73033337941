"""The offline interactive page (o3dheat.visualization.page): its data decoded in Python, its text free
of URLs that would be fetched, and the page drawn by headless Chromium (tests/visualization/browser.py)
on a closed mesh, a mesh with boundary and a mesh of three parts."""

import base64
import gzip
import html
import io
import json
import re

import numpy as np
import open3d as o3d
import pytest
from browser import Browser, changed, drawn, unavailable

import o3dheat
from o3dheat.visualization.page import page_html
from o3dheat.visualization.scene import ScaleField, Scene

T_SCALES = np.geomspace(2e-3, 0.5, 6)


# ------------------------------------------------------------------ test scenes, from the dataclasses
def arrays(m):
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.triangles, dtype=np.int64)


def torus():
    return arrays(o3d.geometry.TriangleMesh.create_torus(1.0, 0.4, 48, 24))


def hemisphere():
    """The upper half of a sphere (an open surface), its pole along +y (drawn with up="y")."""
    V, F = arrays(o3d.geometry.TriangleMesh.create_sphere(1.0, 24))
    F = F[V[F].mean(axis=1)[:, 2] > 0]
    used = np.unique(F)
    index = np.full(len(V), -1)
    index[used] = np.arange(len(used))
    return V[used][:, [1, 2, 0]], index[F]  # y (new) = z (old)


def three_parts():
    m = (o3d.geometry.TriangleMesh.create_torus()
         + o3d.geometry.TriangleMesh.create_sphere().translate((3.0, 0.0, 0.0))
         + o3d.geometry.TriangleMesh.create_icosahedron().subdivide_loop(2).translate((-3.0, 0.0, 0.0)))
    return arrays(m)


def scale_field(V, F, f, name, times=T_SCALES, label="heat flow"):
    values = o3dheat.heat_flow((V, F), f, times)
    critical = tuple(o3dheat.critical_points((V, F), values[:, j]) for j in range(values.shape[1]))
    eps = np.abs(values - f[:, None]).max(axis=0)
    return ScaleField(name, values, np.asarray(times, dtype=np.float64), critical, eps, label)


def bumpy(V, up, seed=0):
    rng = np.random.default_rng(seed)
    h = V[:, "xyz".index(up)]
    return h + 0.25 * np.sin(5 * V[:, 0]) * np.cos(4 * V[:, 1] + V[:, 2]) + 0.03 * rng.standard_normal(len(V))


def make_scene(kind):
    if kind == "closed":
        V, F = torus()
        field = scale_field(V, F, bumpy(V, "z"), "height")
        return Scene(V, F, (field,), {"height": o3dheat.track_critical_points((V, F), field.values, T_SCALES)},
                     notes=("welded 2 duplicate vertices",), name="torus")
    if kind == "boundary":
        V, F = hemisphere()
        field = scale_field(V, F, bumpy(V, "y"), "height")
        return Scene(V, F, (field,), {"height": o3dheat.track_critical_points((V, F), field.values, T_SCALES)},
                     up="y", view=(30.0, -60.0), name="hemisphere")
    V, F = three_parts()
    first = scale_field(V, F, bumpy(V, "z"), "height")
    x = o3dheat.heat_flow((V, F), V[:, 0] + 0.1 * np.sin(6 * V[:, 2]), T_SCALES[:4])
    second = ScaleField("x", x, np.full(4, np.nan),
                        tuple(o3dheat.critical_points((V, F), x[:, j]) for j in range(4)), None, "read from a file")
    return Scene(V, F, (first, second), {"height": o3dheat.track_critical_points((V, F), first.values, T_SCALES)},
                 notes=("decimated from 9,000 to 4,524 faces",), name="three parts")


KINDS = ("closed", "boundary", "parts")


@pytest.fixture(scope="module")
def scenes():
    return {kind: make_scene(kind) for kind in KINDS}


# ------------------------------------------------------------------ the page's data, decoded in Python
def decoded(html):
    """``(meta, array)``: the page's JSON block and a function reading one array of its blob."""
    meta = json.loads(re.search(r'id="o3dheat-meta">(.*?)</script>', html, re.S).group(1))
    blob = gzip.decompress(base64.b64decode(re.search(r'id="o3dheat-data">(.*?)</script>', html, re.S).group(1)))
    types = {"Float32Array": "<f4", "Float64Array": "<f8", "Uint32Array": "<u4", "Int32Array": "<i4",
             "Uint16Array": "<u2", "Uint8Array": "u1"}

    def array(key):
        offset, length, kind = meta["layout"][key]
        assert offset % 8 == 0
        return np.frombuffer(blob, dtype=types[kind], count=length, offset=offset)

    return meta, array


def test_quantized_values_decode_within_a_step(scenes):
    scene = scenes["parts"]
    meta, array = decoded(page_html(scene))
    n = len(scene.V)
    for i, field in enumerate(scene.fields):
        fm = meta["fields"][i]
        planes = array(fm["values"]).reshape(-1, 2, n).astype(np.uint16)  # per scale: high bytes, low bytes
        q = planes[:, 0] << 8 | planes[:, 1]
        assert q.shape[0] == field.values.shape[1]
        for j in range(q.shape[0]):
            lo, hi = fm["lo"][j], fm["hi"][j]
            assert (lo, hi) == (field.values[:, j].min(), field.values[:, j].max())
            back = lo + q[j].astype(np.float64) * (hi - lo) / 65535
            assert np.abs(back - field.values[:, j]).max() <= (hi - lo) / 65535
        assert fm["min"] == field.values.min() and fm["max"] == field.values.max()
        assert fm["counts"] == [list(cp.counts) for cp in field.critical]


def test_critical_points_tracks_and_texts_are_in_the_page(scenes):
    scene = scenes["parts"]
    meta, array = decoded(page_html(scene))
    field = scene.fields[0]
    fm = meta["fields"][0]
    crit, off = array(fm["critical"]), fm["offsets"]
    for j, cp in enumerate(field.critical):
        for k, kind in enumerate(("minima", "saddles", "maxima")):
            assert crit[off[3 * j + k]: off[3 * j + k + 1]].tolist() == getattr(cp, kind).tolist()
    tracks = scene.tracks["height"]
    tm = fm["tracks"]
    assert array(tm["vertex"]).reshape(tm["p"], -1).tolist() == tracks.vertex.tolist()
    np.testing.assert_array_equal(array(tm["lifetime"]), tracks.lifetime)  # inf: alive at the last scale
    assert meta["fields"][1]["times"] == [None] * 4 and meta["fields"][1]["eps_inf"] is None
    assert meta["fields"][1]["tracks"] is None
    assert meta["notes"] == list(scene.notes) and meta["name"] == "three parts"
    assert [f["label"] for f in meta["fields"]] == ["heat flow", "read from a file"]
    assert len(meta["lut"]) == 768 and meta["closed"] is True


def test_positions_are_turned_so_that_up_is_the_third_axis(scenes):
    scene = scenes["boundary"]  # up = "y"
    meta, array = decoded(page_html(scene))
    P = array("positions").reshape(-1, 3)
    c = (scene.V.min(0) + scene.V.max(0)) / 2
    np.testing.assert_allclose(P, (scene.V - c)[:, [2, 0, 1]], atol=1e-6)
    assert meta["closed"] is False  # a boundary: both sides drawn
    assert array("faces").reshape(-1, 3).tolist() == scene.F.tolist()


def test_no_url_would_be_fetched(scenes):
    html = page_html(scenes["closed"])
    # nothing loaded from elsewhere: no src/href/url()/import/fetch of an http(s) or protocol-relative URL
    loads = re.findall(r"""(?:src|href|action|poster)\s*=\s*["']?\s*(?:https?:)?//|url\(\s*["']?\s*(?:https?:)?//"""
                       r"""|@import|import\s*\(?\s*["'](?:https?:)?//|fetch\(\s*["'](?:https?:)?//"""
                       r"""|new\s+(?:Worker|WebSocket|EventSource)\(""", html, re.I)
    assert loads == []
    # the only absolute URL in the page is the XHTML namespace (three.js's document.createElementNS)
    assert set(re.findall(r"https?://[^\s\"'`)<>]+", html)) == {"http://www.w3.org/1999/xhtml"}
    assert "<script src" not in html and "<link" not in html


def test_texts_cannot_break_out_of_the_page(scenes):
    s = scenes["closed"]
    evil = Scene(s.V, s.F, s.fields, name="</script><script>alert(1)</script>", notes=("a & b <i>",))
    html = page_html(evil)
    assert "<script>alert" not in html and html.count("</script>") == page_html(s).count("</script>")
    meta, _ = decoded(html)
    assert meta["name"] == evil.name and meta["notes"] == ["a & b <i>"]


def test_three_js_is_inlined_as_a_classic_script():
    from o3dheat.visualization import page

    src = page._three()
    assert "export{" not in src and re.search(r"return \{[^}]*WebGLRenderer:", src)
    assert 'const t="170"' in src  # the vendored r170 (_page/three/README.md)


def test_a_scene_is_checked(scenes):
    s = scenes["closed"]
    with pytest.raises(o3dheat.MeshError, match="values must be"):
        page_html(Scene(s.V, s.F, (ScaleField("f", s.fields[0].values[:-1], T_SCALES, s.fields[0].critical),)))
    with pytest.raises(o3dheat.MeshError, match="not one of the scene's fields"):
        page_html(Scene(s.V, s.F, s.fields, {"nope": s.tracks["height"]}))
    with pytest.raises(o3dheat.MeshError, match="colormap"):
        page_html(Scene(s.V, s.F, s.fields, cmap="no-such-map"))
    with pytest.raises(o3dheat.MeshError, match="up must be"):
        page_html(Scene(s.V, s.F, s.fields, up="w"))
    with pytest.raises(o3dheat.MeshError, match="CriticalPoints"):
        page_html(Scene(s.V, s.F, (ScaleField("f", s.fields[0].values, T_SCALES, s.fields[0].critical[:2]),)))


# ------------------------------------------------------------------ the page in a browser
def counts(cp):
    """What the page's ``o3dheat.counts()`` returns for the CriticalPoints ``cp``."""
    m, s, M = cp.counts
    return {"minima": m, "saddles": s, "maxima": M}


@pytest.fixture(scope="module")
def browser():
    reason = unavailable()
    if reason:
        pytest.skip(reason)
    b = Browser()
    yield b
    b.close()


@pytest.fixture(scope="module", params=KINDS)
def opened(request, scenes, browser, tmp_path_factory):
    scene = scenes[request.param]
    path = tmp_path_factory.mktemp("page") / f"{request.param}.html"
    path.write_text(page_html(scene), encoding="utf-8")
    page = browser.open(path)
    yield scene, page
    page.close()


def test_the_page_draws_the_surface(opened):
    scene, page = opened
    assert page.js("o3dheat.error") is None and page.errors == []
    assert page.js("o3dheat.ready") is True
    page.set_scale(0)
    assert drawn(page.picture()) > 0.05  # the surface, not a blank canvas


def test_the_scale_changes_the_picture_and_the_counts(opened):
    scene, page = opened
    field = scene.fields[0]
    assert page.js("o3dheat.field") == field.name
    assert page.js("o3dheat.scales") == pytest.approx(field.times.tolist())
    T = len(field.times)
    assert page.set_scale(0) == 0
    first = page.picture()
    assert page.js("o3dheat.counts()") == counts(field.critical[0])
    assert page.set_scale(T - 1) == T - 1
    last = page.picture()
    assert page.js("o3dheat.counts()") == counts(field.critical[-1])
    assert changed(first, last) > 0.01
    page.set_scale(0)
    assert changed(first, page.picture()) < 0.002  # the same scale, the same picture
    assert page.js("document.getElementById('o3h-counts').textContent").startswith(
        f"{field.critical[0].counts[0]} minim")


def near(a, b, tolerance=2) -> float:
    """The fraction of pixels that differ by more than ``tolerance`` (in any channel) between two pictures."""
    return float(np.any(np.abs(a.astype(int) - b.astype(int)) > tolerance, axis=2).mean())


def plain_picture(page, i):
    """The picture of scale ``i`` drawn the plain way (every triangle redrawn), then the deferred way back."""
    assert page.js("o3dheat.setDeferred(false)") is False
    page.set_scale(i)
    assert page.js("o3dheat.timing.path") == "plain"
    img = page.picture()
    assert page.js("o3dheat.setDeferred(true)") is True
    return img


@pytest.fixture
def deferred(opened):
    """The page of ``opened`` recolouring by its deferred pass (on by default from 100k faces in software
    WebGL: forced on for the small test meshes), as it was afterwards."""
    scene, page = opened
    default = page.js("o3dheat.deferred")
    assert default is False  # a small mesh: redrawn the plain way ...
    assert page.js("o3dheat.setDeferred(true)") is True  # ... but SwiftShader can draw the deferred way
    yield scene, page
    page.js("(on) => o3dheat.setDeferred(on)", default)


def test_the_recoloured_picture_is_the_plain_one(deferred):
    """A scale change recolours the G-buffer of the resting view: the same picture as drawing every
    triangle, overlays (level sets, markers, tracks) included."""
    scene, page = deferred
    for i in (0, -1, 2):
        page.set_scale(i)
        assert page.js("o3dheat.timing.path") == "deferred"
        recoloured = page.picture()
        plain = plain_picture(page, i)
        assert drawn(recoloured) > 0.05
        assert near(recoloured, plain) < 1e-4, f"scale {i}"
    page.js("o3dheat.setRange('scale')")  # colours over this scale's range, and its level sets
    page.set_scale(1)
    assert page.js("o3dheat.timing.path") == "deferred"
    recoloured = page.picture()
    assert near(recoloured, plain_picture(page, 1)) < 1e-4
    page.js("o3dheat.setRange('global')")


def test_orbiting_after_scale_changes_draws_the_new_view(deferred):
    """Scale changes, then an orbit (drawn the plain way while the camera moves), then scale changes
    again: the plain way until the camera has rested, then by recolouring the new view's G-buffer, not
    the old one's."""
    scene, page = deferred
    rest = "() => new Promise((r) => setTimeout(r, 400))"  # longer than the page waits to redraw the G-buffer
    page.set_scale(0)
    page.set_scale(-1)
    before = page.picture()
    canvas = page.page.locator("#o3h-canvas")
    canvas.focus()
    for _ in range(3):
        canvas.press("ArrowLeft")
        page.js("() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")
    assert changed(before, page.picture()) > 0.01  # the view turned
    # a scale change while the camera moves: the G-buffer is out of date, not used
    assert page.js("""() => { const c = document.getElementById('o3h-canvas');
        c.dispatchEvent(new KeyboardEvent('keydown', {key: 'ArrowLeft'}));
        o3dheat.setScale(0); return o3dheat.timing.path; }""") == "plain"
    page.set_scale(0)
    moving = page.picture()
    page.js(rest)  # the camera rests: the G-buffer of the new view is drawn
    page.set_scale(-1)
    assert page.js("o3dheat.timing.path") == "deferred"
    last = page.picture()
    assert changed(before, last) > 0.01
    assert near(last, plain_picture(page, -1)) < 1e-4
    assert near(moving, plain_picture(page, 0)) < 1e-4
    page.js("o3dheat.resetView()")
    page.js(rest)
    page.set_scale(-1)
    assert page.js("o3dheat.timing.path") == "deferred"
    assert near(page.picture(), before) < 1e-4


def test_the_page_asks_for_nothing(opened):
    _, page = opened
    assert page.outside() == [] and page.blocked == []


def test_the_slider_works_with_the_keyboard(opened):
    scene, page = opened
    page.set_scale(0)
    page.page.focus("#o3h-scale")
    page.page.keyboard.press("ArrowRight")
    assert page.js("o3dheat.scale") == 1
    assert page.js("o3dheat.counts()")["saddles"] == scene.fields[0].critical[1].counts[1]
    page.page.keyboard.press("End")
    assert page.js("o3dheat.scale") == len(scene.fields[0].times) - 1


def test_level_sets_and_markers_are_drawn(opened):
    _, page = opened
    page.set_scale(0)
    both = page.picture()
    page.js("o3dheat.setLevels(false)")
    page.set_scale(0)
    no_levels = page.picture()
    page.js("o3dheat.setMarkers(false)")
    page.set_scale(0)
    bare = page.picture()
    page.js("o3dheat.setLevels(true); o3dheat.setMarkers(true)")
    dark = lambda img: int((img.max(axis=2) < 70).sum())  # noqa: E731  the level sets' dark lines
    assert dark(both) > dark(no_levels) + 100
    assert changed(no_levels, bare) > 0.0005


def test_the_lifetime_threshold_filters_the_tracks(opened):
    scene, page = opened
    tracks = scene.tracks["height"]
    steps = np.unique(tracks.lifetime[np.isfinite(tracks.lifetime)])
    assert len(steps) >= 2  # the test scenes have tracks that end
    page.js("o3dheat.setLifetime(-Infinity)")
    page.set_scale(-1)
    every = page.picture()
    assert page.js("o3dheat.setLifetime(Infinity)") == np.inf  # only the tracks alive at the last scale
    assert page.js("document.getElementById('o3h-life-value').textContent").startswith("∞")
    page.set_scale(-1)
    moving = [p for p in range(len(tracks)) if np.isfinite(tracks.lifetime[p])
              and len(set(tracks.vertex[p][tracks.vertex[p] >= 0].tolist())) > 1]
    if moving:  # ended tracks that moved: their tubes are gone
        assert changed(every, page.picture()) > 0
    assert page.js("o3dheat.setLifetime", float(steps[1]) * 0.999) == pytest.approx(steps[1])  # snaps up
    assert page.js("document.getElementById('o3h-life').value") == "2"
    page.js("o3dheat.setLifetime(-Infinity)")


def test_hovering_reads_a_vertex(scenes, browser, tmp_path):
    scene = scenes["boundary"]
    path = tmp_path / "hover.html"
    path.write_text(page_html(scene), encoding="utf-8")
    page = browser.open(path)
    try:
        box = page.page.locator("#o3h-canvas").bounding_box()
        page.page.mouse.move(box["x"] + (box["width"] - 110) / 2, box["y"] + box["height"] / 2)
        page.page.wait_for_function("document.getElementById('o3h-readout').textContent.length > 0", timeout=10000)
        text = page.js("document.getElementById('o3h-readout').textContent")
        v = int(re.search(r"vertex (\d+)", text).group(1))
        value = float(re.search(r"= ([−\-0-9.e]+)", text).group(1).replace("−", "-"))
        f = scene.fields[0].values[:, 0]
        assert abs(value - f[v]) <= 1e-4 * (np.ptp(f) + 1e-12) + 1e-5 * abs(f[v])
    finally:
        page.close()


def test_a_second_field_is_chosen(scenes, browser, tmp_path):
    scene = scenes["parts"]
    path = tmp_path / "fields.html"
    path.write_text(page_html(scene), encoding="utf-8")
    page = browser.open(path)
    try:
        assert page.js("o3dheat.fields") == ["height", "x"]
        page.set_scale(-1)  # scale 5 of "height": "x" has 4, the page shows its last
        before = page.picture()
        page.page.select_option("#o3h-field", label="x")
        assert page.js("[o3dheat.field, o3dheat.scale, o3dheat.scales]") == ["x", 3, [None] * 4]
        assert page.js("o3dheat.counts()") == counts(scene.fields[1].critical[3])
        assert changed(before, page.picture()) > 0.01
        assert page.errors == [] and page.outside() == []
    finally:
        page.close()


def test_the_page_works_in_an_iframe_srcdoc(scenes, browser, tmp_path):
    """As a notebook shows it: the page's text in the srcdoc attribute of an iframe."""
    scene = scenes["closed"]
    host = tmp_path / "notebook.html"
    host.write_text(f'<!DOCTYPE html><iframe srcdoc="{html.escape(page_html(scene))}" width="900" height="600">'
                    "</iframe>", encoding="utf-8")
    page = browser.open(host, wait=False)
    try:
        frame = page.page.frames[1]
        page.wait(frame)
        assert frame.evaluate("[o3dheat.ready, o3dheat.error]") == [True, None]
        frame.evaluate(f"o3dheat.setScale({len(scene.fields[0].times) - 1})")
        assert frame.evaluate("o3dheat.counts()") == counts(scene.fields[0].critical[-1])
        png = page.page.locator("iframe").screenshot()
        from PIL import Image

        assert drawn(np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))[:, 280:-130]) > 0.05
        assert page.errors == [] and page.outside() == []
    finally:
        page.close()


def test_the_data_deflated_in_pieces_inflate_in_python_and_in_the_browser(scenes, browser, tmp_path, monkeypatch):
    """The blob's deflate stream is made in pieces on several threads (pigz's method): any split
    inflates to the same bytes, by gzip.decompress and by the browser's DecompressionStream (here
    with 4 KiB pieces, dozens of them: the page reads the same data and counts)."""
    import os

    from o3dheat.visualization import page as page_module

    def gz(data, piece=None):
        return page_module._Deflater(piece).feed(data).finish()

    for data in (b"", b"x", os.urandom(10_000), bytes(range(256)) * 1000):
        for piece in (None, 1, 4095, 4096, 10_000):
            if len(data) // (piece or 1 << 30) < 3000:
                assert gzip.decompress(gz(data, piece)) == data
    scene = scenes["parts"]
    monkeypatch.setattr(page_module, "_PIECE", 4096)
    text = page_html(scene)
    blob = base64.b64decode(re.search(r'id="o3dheat-data">(.*?)</script>', text, re.S).group(1))
    assert blob.count(b"\x00\x00\xff\xff") >= 10  # the sync flushes between pieces
    path = tmp_path / "pieces.html"
    path.write_text(text, encoding="utf-8")
    page = browser.open(path)
    try:
        assert page.js("o3dheat.error") is None and page.js("o3dheat.ready") is True
        last = len(scene.fields[0].times) - 1
        page.set_scale(last)
        assert page.js("o3dheat.counts()") == counts(scene.fields[0].critical[-1])
        assert drawn(page.picture()) > 0.05 and page.errors == []
    finally:
        page.close()


def test_faces_are_16_bit_up_to_65535_vertices_and_32_bit_beyond(browser, tmp_path):
    """The index type follows the mesh's size: uint16 only below index 65535 (WebGL 2 restarts the
    primitive at 65535 in a uint16 index buffer: a mesh of exactly 65,536 vertices lost triangles);
    a 72k-vertex sphere's page has uint32 faces, draws, and counts as Python does."""
    from o3dheat.topology import CriticalPoints

    for count, kind in ((65535, "Uint16Array"), (65536, "Uint32Array")):
        side = 256
        g = np.arange(side * side).reshape(side, side)[: (count + side - 1) // side]
        Vg = np.c_[np.indices(g.shape).reshape(2, -1).T, np.zeros(g.size)].astype(np.float64)[:count]
        quads = np.c_[g[:-1, :-1].ravel(), g[1:, :-1].ravel(), g[1:, 1:].ravel(), g[:-1, 1:].ravel()]
        Fg = np.r_[quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]
        Fg = Fg[(Fg < count).all(axis=1)]
        e = np.zeros(0, np.int64)
        cp = CriticalPoints(e, e, e, e, count)
        grid = Scene(Vg, Fg, (ScaleField("x", Vg[:, :1], np.ones(1), (cp,)),))
        assert decoded(page_html(grid))[0]["layout"]["faces"][2] == kind
    m = o3d.geometry.TriangleMesh.create_sphere(1.0, 190)
    V, F = arrays(m)
    assert len(V) > 65536
    field = scale_field(V, F, V[:, 2], "height", times=[1e-3, 1e-2])
    scene = Scene(V, F, (field,), name="big sphere")
    text = page_html(scene)
    meta, array = decoded(text)
    assert meta["layout"]["faces"][2] == "Uint32Array" and array("faces").reshape(-1, 3).tolist() == F.tolist()
    small = decoded(page_html(make_scene("closed")))[0]
    assert small["layout"]["faces"][2] == "Uint16Array"
    path = tmp_path / "big.html"
    path.write_text(text, encoding="utf-8")
    page = browser.open(path)
    try:
        assert page.js("o3dheat.error") is None and page.js("o3dheat.ready") is True
        page.set_scale(1)
        assert page.js("o3dheat.counts()") == counts(field.critical[1])
        assert drawn(page.picture()) > 0.05 and page.errors == []
    finally:
        page.close()


def test_without_webgl_the_page_says_so(scenes, browser, tmp_path):
    path = tmp_path / "nogl.html"
    path.write_text(page_html(scenes["closed"]), encoding="utf-8")
    page = browser.open(path, init="const get = HTMLCanvasElement.prototype.getContext; "
                                   "HTMLCanvasElement.prototype.getContext = function (kind, options) { "
                                   "return /webgl/.test(kind) ? null : get.call(this, kind, options); };")
    try:
        error = page.js("o3dheat.error")
        assert page.js("o3dheat.ready") is False and "WebGL" in error
        assert "WebGL" in page.js("document.getElementById('o3h-message').textContent")
    finally:
        page.close()


def test_the_request_guard_sees_requests(browser, tmp_path):
    """The guard of test_the_page_asks_for_nothing would see a request: here a page makes two."""
    path = tmp_path / "asks.html"
    path.write_text("<!DOCTYPE html><img src='http://example.invalid/a.png'><script>window.o3dheat = {ready: true};"
                    "fetch('https://example.invalid/b.json').catch(() => 0)</script>", encoding="utf-8")
    page = browser.open(path)
    try:
        page.page.wait_for_timeout(300)
        assert set(page.outside()) >= {"http://example.invalid/a.png", "https://example.invalid/b.json"}
    finally:
        page.close()


def test_the_page_draws_no_track_move_the_figures_leave_out():
    """A track's move between two scales longer than the figures' limit (5% of the diagonal, or 2.5
    edges) would cut across the surface: the page gets the same limit (one rule, _tracks.longest_move)."""
    import json
    import re

    from o3dheat.visualization._tracks import longest_move

    V, F = torus()
    f = V[:, 0]
    cp = tuple(o3dheat.critical_points((V, F), f * s) for s in (1.0, 0.5))
    html = page_html(Scene(V, F, (ScaleField("x", np.c_[f, 0.5 * f], np.array([0.0, 1.0]), cp),)))
    meta = json.loads(re.search(r'id="o3dheat-meta">(.*?)</script>', html, re.S).group(1))
    assert meta["jump"] == pytest.approx(longest_move(V, F)) and meta["jump"] > 0


def test_closed_means_every_edge_has_two_faces():
    """The page draws front faces only on closed surfaces: ``_closed`` against the count of each
    edge's faces, on random face soups (edges of 1, 2, 3+ faces), a sphere, and a sphere with a hole."""
    from o3dheat.visualization.page import _closed

    def by_count(F, n):
        edges = {}
        for f in F.tolist():
            for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
                edges[min(a, b), max(a, b)] = edges.get((min(a, b), max(a, b)), 0) + 1
        return all(c == 2 for c in edges.values())

    m = o3d.geometry.TriangleMesh.create_sphere(1.0, 10)
    F0 = np.asarray(m.triangles).astype(np.int64)
    assert _closed(F0, len(m.vertices)) and not _closed(F0[1:], len(m.vertices))
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(400):
        n = int(rng.integers(3, 6))
        F = np.array([rng.choice(n, 3, replace=False) for _ in range(int(rng.integers(1, 9)))])
        seen.add(by_count(F, n))
        assert _closed(F, n) == by_count(F, n), F.tolist()
    assert seen == {True, False}
