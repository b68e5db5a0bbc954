"""Uploads the lab can afford (issue 51, item 4; ``armlab.app.viser_ext.uploads``).

A served lab and headless pages that send what a browser sends (or what a hostile page
would): a page's unfinished uploads are bounded in number and bytes, all pages' together
in bytes; a page that leaves mid-upload leaves nothing behind; every upload that fails is
answered with one notification on the page that sent it.
"""

from __future__ import annotations

import sys

import pytest
import test_hostile_runs as hostile
from _helpers import settled, wait_for

from armlab.app.lessons.run_files import REFUSED
from armlab.app.testing.wsclient import HeadlessClient
from armlab.app.viser_ext import uploads
from armlab.app.viser_ext.uploads import (
    MAX_PAGE_UPLOAD_BYTES,
    MAX_PAGE_UPLOADS,
    MAX_TOTAL_UPLOAD_BYTES,
    unfinished,
)
from armlab.control.runs import MAX_FILE_BYTES

pytestmark = [pytest.mark.realtime, pytest.mark.slow]  # a served lab on the wall clock

PART = 512 * 1024


def open_page(lab) -> HeadlessClient:
    c = HeadlessClient(lab.url.replace("http://", "ws://")).connect()
    c.wait_for(lambda: c.shows("Open run"), what="the Files tab")
    settled(lab.server, c)
    return c


def refusals(page: HeadlessClient) -> list[str]:
    return [body for title, body in page.notifications if title == REFUSED]


def start_partial(page: HeadlessClient, name: str, declared: int) -> str:
    """An upload declaring ``declared`` bytes of which only the first part is sent."""
    return page.upload("Open run", name, b"p" * declared, part_bytes=max(declared // 4, 1),
                       only=[0]) if declared <= 4 * PART else page.upload(
        "Open run", name, b"p" * (2 * PART), part_bytes=PART, declared=declared, only=[0])


def kept(lab, transfer: str) -> bool:
    return transfer in lab.server.gui._current_file_upload_states


@pytest.fixture
def pages(lab):
    opened: list[HeadlessClient] = []

    def make() -> HeadlessClient:
        opened.append(open_page(lab))
        return opened[-1]

    yield make
    for c in opened:
        c.close()
    wait_for(lambda: unfinished() == (0, 0), 30.0, "the pages' uploads to be dropped")


def test_a_page_may_have_two_unfinished_uploads_and_80_mib(lab, pages):
    page = pages()
    first = start_partial(page, "a.armlab-run.zip", 40 * 2**20)
    second = start_partial(page, "b.armlab-run.zip", 30 * 2**20)
    page.wait_for(lambda: kept(lab, first) and kept(lab, second), what="both kept")
    assert MAX_PAGE_UPLOADS == 2
    third = start_partial(page, "c.armlab-run.zip", 1024)
    page.wait_for(lambda: any("c.armlab-run.zip" in r for r in refusals(page)),
                  what="the third refused")
    assert "still sending 2 file(s)" in refusals(page)[-1]
    assert not kept(lab, third)
    # bytes: one file of 64 MiB beside one of 30 MiB passes the 80 MiB of a page
    other = pages()
    start_partial(other, "big.armlab-run.zip", MAX_FILE_BYTES)
    start_partial(other, "more.armlab-run.zip", MAX_PAGE_UPLOAD_BYTES - MAX_FILE_BYTES + 1)
    other.wait_for(lambda: any("more.armlab-run.zip" in r for r in refusals(other)),
                   what="the bytes past 80 MiB refused")
    assert "80 MiB in all" in refusals(other)[-1]


def test_all_pages_together_may_have_256_mib_unfinished(lab, pages):
    many = [pages() for _ in range(MAX_TOTAL_UPLOAD_BYTES // MAX_FILE_BYTES + 1)]
    held = [start_partial(p, f"p{i}.armlab-run.zip", MAX_FILE_BYTES)
            for i, p in enumerate(many[:-1])]
    wait_for(lambda: all(kept(lab, t) for t in held), 30.0, "four uploads kept")
    assert unfinished()[1] == MAX_TOTAL_UPLOAD_BYTES
    last = many[-1]
    refused = start_partial(last, "fifth.armlab-run.zip", 1024)
    last.wait_for(lambda: any("fifth" in r for r in refusals(last)), what="the fifth refused")
    assert "the lab is receiving 256 MiB" in refusals(last)[-1]
    assert not kept(lab, refused)
    # one page leaves: its upload goes, and another page's file then fits
    many[0].close()
    wait_for(lambda: not kept(lab, held[0]), 30.0, "the departed page's upload dropped")
    after = start_partial(last, "sixth.armlab-run.zip", 1024)
    last.wait_for(lambda: kept(lab, after), what="a new upload taken")


def test_a_page_that_leaves_mid_upload_leaves_nothing_behind(lab, pages):
    page = pages()
    content = b"z" * (20 * 2**20)
    transfer = page.upload("Open run", "left.armlab-run.zip", content, part_bytes=PART,
                           only=list(range(30)))  # 15 of its 20 MiB, then it leaves
    states = lab.server.gui._current_file_upload_states
    page.wait_for(lambda: kept(lab, transfer) and len(states[transfer]["parts"]) == 30,
                  what="the parts kept")
    part = states[transfer]["parts"][0]
    page.close()
    wait_for(lambda: not kept(lab, transfer), 30.0, "the upload dropped")
    assert unfinished() == (0, 0)
    assert sys.getrefcount(part) == 2  # this name and the call's: the lab holds no part


@pytest.mark.parametrize("how,says", [
    ("a part out of range", "out of order"),
    ("a part sent twice", "out of order"),
    ("fewer bytes than declared", "add up to less than the page declared"),
    ("another page's upload", "another page's upload"),
    ("the open fails", "could not be opened (RuntimeError"),
])
def test_every_failing_upload_is_answered_on_its_page(lab, pages, monkeypatch, how, says):
    page = pages()
    before = len(refusals(page))
    if how == "a part out of range":
        page.upload("Open run", "r.armlab-run.zip", b"x" * 2048, part_bytes=1024, only=[0, 7])
    elif how == "a part sent twice":
        page.upload("Open run", "r.armlab-run.zip", b"x" * 3072, part_bytes=1024,
                    only=[0, 0])
    elif how == "fewer bytes than declared":
        page.upload("Open run", "r.armlab-run.zip", b"x" * 2048, part_bytes=1024,
                    declared=4096)
    elif how == "another page's upload":
        owner = pages()
        transfer = start_partial(owner, "theirs.armlab-run.zip", 4096)
        owner.wait_for(lambda: kept(lab, transfer), what="the owner's upload")
        page.send({"type": "FileTransferPart",
                   "source_component_uuid": uploads_uuid(page), "transfer_uuid": transfer,
                   "part_index": 1, "content": b"q" * 1024})
    else:
        def broken(name, content):
            raise RuntimeError("a bug")

        monkeypatch.setattr(lab.lesson.runs, "open_bytes", broken)
        page.upload("Open run", "r.armlab-run.zip", b"x" * 100)
    page.wait_for(lambda: len(refusals(page)) > before, what="the page told")
    assert says in refusals(page)[-1]
    settled(lab.server, page)
    assert len(refusals(page)) == before + 1  # one notification, not one a part


@pytest.mark.parametrize("case", ["4000-digit integer in a gain", "2 MB string in the robot",
                                  "a member name with a NUL", "bzip2 member"])
def test_a_hostile_file_is_answered_with_its_short_line(lab, pages, case):
    """What killed the upload handler (a 4000-digit gain) or filled the page (a 2 MB
    string) is one short notification; the lab goes on."""
    make, says = next((m, w) for c, m, w in hostile.HOSTILE if c == case)
    page = pages()
    before = len(refusals(page))
    page.upload("Open run", "hostile.armlab-run.zip", make())
    page.wait_for(lambda: len(refusals(page)) > before, 60.0, what="the page told")
    told = refusals(page)[-1]
    assert told.startswith("hostile.armlab-run.zip") and len(told) <= 320, told[:1000]
    if case != "2 MB string in the robot":  # the lab's robot is checked first there
        assert says in told
    settled(lab.server, page)
    assert len(refusals(page)) == before + 1


def uploads_uuid(page: HeadlessClient) -> str:
    """The uuid of the page's Open run button."""
    return page._uuid("Open run", "GuiUploadButtonMessage")


def test_the_limits_are_stated():
    assert (uploads.MAX_PAGE_UPLOADS, uploads.MAX_PAGE_UPLOAD_BYTES // 2**20,
            uploads.MAX_TOTAL_UPLOAD_BYTES // 2**20) == (2, 80, 256)
