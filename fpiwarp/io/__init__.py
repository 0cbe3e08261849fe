"""Image files: reading and writing without losing pixels, metadata or files.

* :mod:`.images`: :func:`read_image` and :func:`write_image`, the one entry;
* :mod:`.formats`: what each format can store and which codec handles it;
* :mod:`.pillow`, :mod:`.png`, :mod:`.tiff`: the codecs;
* :mod:`.orientation`: EXIF orientation;
* :mod:`.atomic`: writes that leave no partial file.
"""

from .images import *  # noqa: F403 - the package's public names are those of .images
from .images import __all__  # noqa: F401
