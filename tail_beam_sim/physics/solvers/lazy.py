"""A value computed on its first read and kept on the instance: ``functools.cached_property``
without its lock.

Python 3.11's cached_property takes a lock on every first read, which costs more than the small
computations of a contact kept this way (a pulse's samples, a segment's states), several per
simulated impact. Without the lock two threads reading the same attribute of the same new
object at once may both compute it; the values are equal, and these objects are not shared
between threads while they are being filled.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, TypeVar, overload

T = TypeVar("T")


class lazy(Generic[T]):
    """Decorates a method of one argument: the attribute of that name is its value, computed on
    the first read and stored in the instance's ``__dict__``, where later reads find it."""

    def __init__(self, function: Callable[[Any], T]) -> None:
        self.function = function
        self.name = function.__name__
        self.__doc__ = function.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> lazy[T]: ...

    @overload
    def __get__(self, instance: object, owner: type | None = None) -> T: ...

    def __get__(self, instance: object | None, owner: type | None = None) -> T | lazy[T]:
        if instance is None:
            return self
        value = instance.__dict__[self.name] = self.function(instance)
        return value
