"""The plain look for pages drawing WebGL in software (armlab.app.page.look), without a browser: the
renderer names, and a served lab asking a headless page (armlab.app.testing.wsclient answers the
server's localStorage questions as a page does)."""

from __future__ import annotations

import pytest
from _helpers import wait_for

from armlab.app.lab.server import Lab, ServeOptions
from armlab.app.page.look import RENDERER_KEY, is_software
from armlab.app.testing.wsclient import HeadlessClient

#: WebGL renderer names as browsers report them (UNMASKED_RENDERER_WEBGL)
SOFTWARE = ("ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device (Subzero) (0x0000C0DE)), "
            "SwiftShader driver)",
            "llvmpipe (LLVM 15.0.6, 256 bits)",
            "Google SwiftShader",
            "Microsoft Basic Render Driver (software adapter)")
GPU = ("ANGLE (NVIDIA, NVIDIA GeForce RTX 3060 Direct3D11 vs_5_0 ps_5_0, D3D11)",
       "Mesa Intel(R) UHD Graphics 620 (KBL GT2)",
       "ANGLE (Apple, ANGLE Metal Renderer: Apple M1, Unspecified Version)",
       "Adreno (TM) 640", "Mali-G78", "")


@pytest.mark.parametrize("name", SOFTWARE)
def test_software_renderers_are_recognised(name):
    assert is_software(name)


@pytest.mark.parametrize("name", GPU)
def test_gpu_renderers_keep_the_full_look(name):
    assert not is_software(name)


def _page(lab: Lab, renderer: str | None, seen: list[dict]) -> HeadlessClient:
    """A headless page whose localStorage already names ``renderer`` (what the probe
    script writes in a browser; None: a page that ran no script)."""
    page = HeadlessClient(lab.local_url.replace("http://", "ws://"),
                          on_message=lambda m, _t: seen.append(m))
    if renderer is not None:
        page.local_storage[RENDERER_KEY] = renderer
    return page.connect()


def _plain_sent(seen: list[dict]) -> bool:
    """The page was told to draw without the environment map or without shadows."""
    return any((m["type"] == "EnvironmentMapMessage" and m["hdri_data"] is None)
               or (m["type"] == "EnableLightsMessage" and not m["cast_shadow"]) for m in seen)


def _only(lab: Lab, known: set[int]) -> int:
    (cid,) = set(lab.server.get_clients()) - known
    return cid


def test_a_software_page_alone_gets_the_plain_look_and_a_gpu_page_keeps_the_full_one():
    with Lab(ServeOptions(http_port=0)) as lab:
        known = set(lab.server.get_clients())
        soft_seen: list[dict] = []
        with _page(lab, SOFTWARE[0], soft_seen):
            wait_for(lambda: len(set(lab.server.get_clients()) - known) == 1, 60, "the page")
            soft = _only(lab, known)
            wait_for(lambda: lab.looks.is_plain(soft) and lab.looks.settled(soft), 60,
                     "the plain look, settled")
            wait_for(lambda: any(m["type"] == "EnableLightsMessage" for m in soft_seen), 60,
                     "the page to get the lights without shadows")
            env = [m for m in soft_seen if m["type"] == "EnvironmentMapMessage"]
            lights = [m for m in soft_seen if m["type"] == "EnableLightsMessage"]
            assert env and env[-1]["hdri_data"] is None
            assert lights[-1]["enabled"] and not lights[-1]["cast_shadow"]
            known.add(soft)
            for renderer in (GPU[0], None):  # a GPU page, and a page without the script
                gpu_seen: list[dict] = []
                with _page(lab, renderer, gpu_seen):
                    wait_for(lambda: len(set(lab.server.get_clients()) - known) == 1, 60,
                             "the page")
                    gpu = _only(lab, known)
                    wait_for(lambda g=gpu: lab.looks.renderer(g) is not None, 60, "its answer")
                    assert lab.looks.renderer(gpu) == (renderer or "")
                    wait_for(lambda g=gpu: lab.looks.settled(g), 60, "its look settled")
                    assert not lab.looks.is_plain(gpu)
                    assert not _plain_sent(gpu_seen)
                wait_for(lambda g=gpu: g not in lab.server.get_clients(), 60, "the page to leave")
                wait_for(lambda g=gpu: lab.looks.renderer(g) is None
                         and not lab.looks.settled(g), 60, "its entry forgotten")
            assert lab.looks.is_plain(soft)  # the software page keeps its plain look


def test_the_full_look_everywhere_when_asked():
    with Lab(ServeOptions(http_port=0, plain_on_software=False)) as lab:
        known = set(lab.server.get_clients())
        seen: list[dict] = []
        with _page(lab, SOFTWARE[0], seen):
            wait_for(lambda: len(set(lab.server.get_clients()) - known) == 1, 60, "the page")
            cid = _only(lab, known)
            wait_for(lambda: lab.looks.renderer(cid) is not None, 60, "its answer")
            assert not lab.looks.is_plain(cid)
            assert not _plain_sent(seen)
