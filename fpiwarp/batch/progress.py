"""A progress bar for folder batches on a terminal (tqdm when installed)."""

import sys
import time


class Progress:
    """A progress bar on a terminal stream (tqdm when installed, else a
    one-line text bar); silent when the stream is not a terminal."""

    def __init__(self, total, stream=None, enabled=None):
        self.stream = stream if stream is not None else sys.stderr
        self.total = total
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.start = time.monotonic()
        self._bar = None
        if self.enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                pass
            else:
                self._bar = tqdm(total=total, file=self.stream, unit="img", leave=False)

    def __call__(self, summary):
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(summary.processed - self._bar.n)
            return
        done, total = summary.processed, max(self.total, 1)
        width = 30
        filled = int(width * done / total)
        rate = done / max(time.monotonic() - self.start, 1e-9)
        line = f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{self.total} files, {rate:.1f}/s"
        if summary.failed:
            line += f", {len(summary.failed)} failed"
        self.stream.write(line)
        self.stream.flush()

    def close(self):
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.close()
        else:
            self.stream.write("\r\033[K")
            self.stream.flush()
