"""The live page's fleet actions in a real headless browser (issue 29, item 5).

Against the fake daemon of test_control_fake.py: "Release all", "RTL all" and "Resume all"
ask for a confirmation first (nothing is sent before it; Cancel sends nothing), then show
each vehicle's answer; a vehicle's own ``rtl`` button answers what happened. Marked
``browser`` (see test_live_map_browser.py for what it needs).
"""

from __future__ import annotations

from typing import Any

import pytest
from test_control_fake import ServerThread
from test_live_map_browser import driver, open_page, wait_for

pytestmark = pytest.mark.browser
__all__ = ["driver"]  # the fixture, imported


def _calls(server: ServerThread) -> list[tuple[Any, ...]]:
    return list(server.call(lambda: list(server.control.calls)))


def test_fleet_buttons_confirm_then_show_each_vehicles_answer(driver: Any) -> None:
    from selenium.webdriver.common.by import By

    drv = driver
    with ServerThread(tick_s=0.1, token="fleet-token", push_hz=5.0) as server:
        open_page(drv, f"{server.url}/?token=fleet-token")
        wait_for(lambda: drv.execute_script("return window.floe.write"), "the token")

        def button(selector: str) -> Any:
            return drv.find_element(By.CSS_SELECTOR, selector)

        before = len(_calls(server))
        button("button[data-fleet=release]").click()
        question = button("#fleet-question")
        assert question.is_displayed() and question.text == "Release all 3 vehicles?"
        assert len(_calls(server)) == before  # nothing sent before the confirmation
        button("#fleet-no").click()
        assert not button("#fleet-confirm").is_displayed()
        assert len(_calls(server)) == before
        button("button[data-fleet=release]").click()
        button("#fleet-yes").click()
        wait_for(lambda: ("fleet", "release") in _calls(server), "the release to be sent")
        items = wait_for(lambda: drv.find_elements(By.CSS_SELECTOR, "#fleet-answer li"),
                         "the answers")
        assert [li.text for li in items] == [f"vehicle uav{i} released" for i in (1, 2, 3)]
        wait_for(lambda: "release all: 3 done, 0 refused" in button("#notice").text,
                 "the summary")
        # one vehicle taken back meanwhile: resume all says which one was refused, and why
        server.call(lambda: server.control.vehicles[1].update(status="active"))
        button("button[data-fleet=resume]").click()
        button("#fleet-yes").click()
        wait_for(lambda: "resume all: 2 done, 1 refused" in button("#notice").text,
                 "the resume summary")
        refused = drv.find_elements(By.CSS_SELECTOR, "#fleet-answer li.error")
        assert [li.text for li in refused] == [
            "vehicle uav2 refused: vehicle uav2 is active already"]
        # a vehicle's own RTL answers what happened
        wait_for(lambda: drv.find_elements(
            By.CSS_SELECTOR, "#vehicles tr[data-id=uav1] button[data-act=rtl]"), "rtl button")
        button("#vehicles tr[data-id=uav1] button[data-act=rtl]").click()
        wait_for(lambda: "vehicle uav1 home" in button("#notice").text, "the rtl answer")
        assert ("vehicle", "uav1", "rtl") in _calls(server)
