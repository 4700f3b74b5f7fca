"""Time and scheduling onboard: clocks and the multi-rate executive."""

from onboard.runtime.clock import Clock, RealTimeClock, SimClock
from onboard.runtime.executive import Executive, Task, TaskStats

__all__ = ["Clock", "Executive", "RealTimeClock", "SimClock", "Task", "TaskStats"]
