"""Take the browser guide's screenshot (docs/guides/browser-editor.png).

The --web page of the bundled sample picture in headless Chromium, with a
local deformation (edges 0 and 2 constrained), the handles, the outline
and the distortion heat map with its legend. Run from the checkout:
``python3 docs/guides/browser_screenshot.py``.
"""

import io
from importlib import resources
from pathlib import Path

from PIL import Image

import fpiwarp
from fpiwarp.widget import browser
from fpiwarp.widget.server import PageServer
from fpiwarp.widget.session import Session

OUT = Path(__file__).with_name("browser-editor.png")


def main():
    path = resources.files("fpiwarp.data").joinpath("sample.png")
    image = fpiwarp.read_image(path)
    h, w = image.shape[:2]
    src = [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]
    dst = [[0.06 * w, 0.04 * h], [0.9 * w, -0.05 * h], [1.04 * w, 1.02 * h], [-0.03 * w, 0.92 * h]]
    session = Session(image, fpiwarp.LocalDeformation(src, dst, edges=(0, 2)),
                      overlays=("handles", "outline", "heatmap"), background=(0.18, 0.18, 0.2, 1.0))
    with PageServer(session) as server:
        driver = browser.launch(size=(860, 600))
        try:
            browser.open_page(driver, server.url)
            png = driver.get_screenshot_as_png()
        finally:
            driver.quit()
    shot = Image.open(io.BytesIO(png)).convert("RGB").quantize(colors=192, method=Image.Quantize.MEDIANCUT)
    shot.save(OUT, optimize=True)
    print(f"wrote {OUT} ({OUT.stat().st_size // 1024} KiB)")


if __name__ == "__main__":
    main()
