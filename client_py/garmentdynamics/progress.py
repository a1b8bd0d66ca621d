"""A progress bar for waiting on jobs: tqdm when installed, else a plain text bar on stderr."""

import sys


class ProgressBar:
    """update(fraction 0..1, text) and close(); does nothing when disabled."""

    def __init__(self, desc: str = "", enabled: bool = True, stream=None):
        self.enabled = enabled
        self.desc = desc
        self.stream = stream or sys.stderr
        self._tqdm = None
        self._last = -1.0
        if not enabled:
            return
        try:
            from tqdm import tqdm
            self._tqdm = tqdm(total=1000, desc=desc, file=self.stream, unit="‰", leave=True)
        except ImportError:
            self._tqdm = None

    def update(self, fraction: float, text: str = "") -> None:
        if not self.enabled:
            return
        fraction = min(max(float(fraction), 0.0), 1.0)
        if self._tqdm is not None:
            self._tqdm.n = int(round(fraction * 1000))
            self._tqdm.set_postfix_str(text, refresh=False)
            self._tqdm.refresh()
            return
        if abs(fraction - self._last) < 0.005 and fraction < 1.0:
            return
        self._last = fraction
        width = 30
        filled = int(round(fraction * width))
        self.stream.write(f"\r{self.desc} [{'#' * filled}{'.' * (width - filled)}] {fraction * 100:5.1f}% {text}")
        self.stream.flush()

    def close(self) -> None:
        if not self.enabled:
            return
        if self._tqdm is not None:
            self._tqdm.close()
        elif self._last >= 0:
            self.stream.write("\n")
            self.stream.flush()
        self.enabled = False
