"""A small least-recently-used cache of objects made on demand."""

from collections import OrderedDict


class LruCache:
    """Up to ``size`` objects by key; the least recently used goes first.

    Examples
    --------
    >>> cache = LruCache(2)
    >>> [cache.lookup(k, lambda: k * 10) for k in (1, 2, 1, 3)]
    [10, 20, 10, 30]
    >>> sorted(cache.keys())  # 2 was used least recently
    [1, 3]
    """

    def __init__(self, size):
        self.size, self._items = size, OrderedDict()

    def lookup(self, key, make):
        """The object of ``key``, made by ``make()`` (and kept) if absent."""
        item = self._items.get(key)
        if item is None:
            item = make()
            self._items[key] = item
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        else:
            self._items.move_to_end(key)
        return item

    def keys(self):
        """The keys held, least recently used first."""
        return list(self._items)

    def clear(self):
        self._items.clear()
