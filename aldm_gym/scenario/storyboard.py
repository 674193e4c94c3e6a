"""The storyboard's life cycle: which elements run, and when the scenario ends.

OpenSCENARIO 1.x (ASAM OpenSCENARIO XML, "Storyboard and entities"): every storyboard
element (story, act, maneuver group, maneuver, event, action) is in one of three states,
``standby``, ``running`` or ``complete``, and moves between them by transitions
(``startTransition``, ``endTransition``, ``stopTransition``, ``skipTransition``) that a
:class:`~aldm_gym.scenario.conditions.StoryboardElementStateCondition` can watch.

- The stories run from the start. An act starts when its start trigger fires (at once
  without one) and ends when all its maneuver groups are complete, or stops when its
  stop trigger fires.
- A maneuver group runs its maneuvers; when all are complete it runs them again, up to
  ``maximumExecutionCount`` times in all.
- A maneuver's events start when their start triggers fire, by ``priority``:
  ``overwrite`` (``override`` since 1.2) stops the maneuver's other running events,
  ``skip`` does not start while another event of the maneuver runs (a skip transition
  that leaves it in standby: it starts once its trigger fires with none running),
  ``parallel`` starts regardless. An event runs its
  actions (on every actor of its maneuver group) and ends when they all have; it can
  start again up to its ``maximumExecutionCount`` (default 1). A maneuver is complete
  when all its events are.
- A trigger fires when one of its condition groups holds; a group holds when all its
  conditions do. A condition's ``conditionEdge`` (``none``, ``rising``, ``falling``,
  ``risingOrFalling``) and ``delay`` [s] apply to its own value; the first evaluation
  has no previous value, so it makes no edge.
- The scenario ends when the storyboard's stop trigger fires; nothing runs after.
- A ``StoryboardElementStateCondition`` on a transition holds at the first evaluation
  after the transition (each condition sees each transition once); on a state, while
  the element is in it.

Where the standard leaves the order open, :meth:`Storyboard.update` evaluates the
triggers top down in document order, then starts the actions of newly started events
at once (a step-shaped action takes effect at this time step).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from aldm_gym.errors import OffRoadError

__all__ = [
    "STATES",
    "TRANSITIONS",
    "Act",
    "ActionElement",
    "Condition",
    "Element",
    "Event",
    "Maneuver",
    "ManeuverGroup",
    "Story",
    "Storyboard",
    "Trigger",
]

STATES = ("standbyState", "runningState", "completeState")
"""The element states, as ``StoryboardElementStateCondition`` names them."""

TRANSITIONS = ("startTransition", "endTransition", "stopTransition", "skipTransition")
"""The transitions, as ``StoryboardElementStateCondition`` names them."""


class Element:
    """A storyboard element: its name, state and the last transition it made.

    :ivar kind: ``story``, ``act``, ``maneuverGroup``, ``maneuver``, ``event`` or
        ``action`` (``StoryboardElementStateCondition``'s ``storyboardElementType``).
    """

    kind = "element"

    def __init__(self, name: str, where: str) -> None:
        """A standby element; ``where`` names it in errors (``file:line <Tag>``)."""
        self.name = name
        self.where = where
        self.state = "standbyState"
        self.transition: str | None = None
        self.transitions: list[str] = []
        """Every transition the element made, in order (conditions keep a cursor)."""
        self.ticks: list[int] = []
        """The storyboard update (1 at time 0) of each of :attr:`transitions`."""
        self.visible: list[int] = []
        """The first update whose conditions see each of :attr:`transitions`."""
        self.state_log: list[tuple[int, str]] = []
        """(first update that sees it, state) of every state change, in order."""
        self.runs = 0

    def _move(self, transition: str, state: str, tick: int, later: bool = False) -> None:
        self.state = state
        self.transition = transition
        self.transitions.append(transition)
        self.ticks.append(tick)
        self.visible.append(tick + 1 if later else tick)
        self.state_log.append((tick + 1 if later else tick, state))

    def _set_state(self, state: str, tick: int, later: bool = False) -> None:
        """A state change without a transition (a reset for a next execution)."""
        self.state = state
        self.state_log.append((tick + 1 if later else tick, state))

    def shows(self, state: str, since: int, tick: int) -> tuple[bool, int]:
        """Whether the element is in ``state`` (a state: after the last transition
        update ``tick`` sees), or made ``state`` (a transition) after the first
        ``since`` of its transitions that update ``tick`` sees; and the cursor past the
        transitions seen."""
        upto = since
        while upto < len(self.transitions) and self.visible[upto] <= tick:
            upto += 1
        if state in STATES:
            now = next((s for v, s in reversed(self.state_log) if v <= tick), "standbyState")
            return now == state, upto
        return state in self.transitions[since:upto], upto


@dataclass(eq=False)
class Condition:
    """One ``Condition``: a value function with its edge and delay.

    :ivar evaluate: ``evaluate(runner) -> bool``, the condition's value now; a
        by-entity condition's also names the triggering entities it held on
        (``evaluate.fulfilled``, see :class:`~aldm_gym.scenario.conditions.ByEntity`).
    :ivar fulfilled: the triggering entities that fulfilled the condition's last value
        (empty when it is false, or for a by-value condition); on a falling edge, those
        that fulfilled it until then.
    """

    name: str
    evaluate: Callable[[Any], bool]
    edge: str = "none"
    delay: float = 0.0
    where: str = ""
    fulfilled: tuple[str, ...] = ()
    _previous: bool | None = None
    _previous_names: tuple[str, ...] = ()
    _history: list[tuple[float, bool, tuple[str, ...]]] = field(default_factory=list)

    def value(self, runner: Any, time: float) -> bool:
        """The condition's value at ``time`` [s] (edge and delay applied)."""
        try:
            now = bool(self.evaluate(runner))
        except OffRoadError:  # an entity on no lane (the function drove it off): false
            now = False
        held: tuple[str, ...] = getattr(self.evaluate, "fulfilled", ()) if now else ()
        before, self._previous = self._previous, now
        held_before, self._previous_names = self._previous_names, held
        # a falling edge is made by the entities that fulfilled the condition until now
        names = held if now else held_before
        if self.edge == "none":
            edged = now
        elif before is None:
            edged = False
        elif self.edge == "rising":
            edged = now and not before
        elif self.edge == "falling":
            edged = before and not now
        else:  # risingOrFalling
            edged = now != before
        if self.delay <= 0.0:
            self.fulfilled = names if edged else ()
            return edged
        self._history.append((time, edged, names if edged else ()))
        cutoff = time - self.delay + 1e-9
        value, self.fulfilled = False, ()
        while self._history and self._history[0][0] <= cutoff:
            _, value, self.fulfilled = self._history.pop(0)
            if value:
                return True
        return value


@dataclass(eq=False)
class Trigger:
    """A start or stop trigger: OR of condition groups, each an AND of conditions.
    No groups: ``empty`` decides (a missing start trigger fires at once, a missing stop
    trigger never)."""

    groups: list[list[Condition]]
    empty: bool
    _held: list[bool] = field(default_factory=list)

    def fires(self, runner: Any, time: float) -> bool:
        """Whether the trigger fires now (every condition is evaluated, so that edges
        and delays see every time step)."""
        if not self.groups:
            return self.empty
        self._held = [all([c.value(runner, time) for c in group]) for group in self.groups]
        return any(self._held)

    def fulfilled(self) -> list[str]:
        """The triggering entities of the last :meth:`fires`: those that fulfilled a
        condition of a group that held, in document order (the standard's triggering
        entities, which ``selectTriggeringEntities`` makes actors)."""
        names: dict[str, None] = {}
        for group, held in zip(self.groups, self._held, strict=False):
            if held:
                for c in group:
                    names.update(dict.fromkeys(c.fulfilled))
        return list(names)


class ActionElement(Element):
    """An ``Action`` of an event: one runtime instance per actor (``instances``)."""

    kind = "action"

    def __init__(self, name: str, where: str, make: Callable[[Any, Any], Any]) -> None:
        """``make(runner, actor) -> instance`` with ``start(runner)``,
        ``done`` and ``stop()``; ``actor`` is ``None`` for a global action."""
        super().__init__(name, where)
        self.make = make
        self.instances: list[Any] = []
        self.rank: tuple[int, ...] = (1, 0)
        """Where the action moves its actors within a step (the storyboard sets it)."""


class Event(Element):
    """An ``Event``: actions, a start trigger, a priority and an execution count."""

    kind = "event"

    def __init__(
        self,
        name: str,
        where: str,
        actions: list[ActionElement],
        start: Trigger,
        priority: str,
        maximum: int,
    ) -> None:
        """See the module docstring."""
        super().__init__(name, where)
        self.actions = actions
        self.start = start
        self.priority = "overwrite" if priority == "override" else priority
        self.maximum = maximum


class Maneuver(Element):
    """A ``Maneuver``: its events."""

    kind = "maneuver"

    def __init__(self, name: str, where: str, events: list[Event]) -> None:
        """See the module docstring."""
        super().__init__(name, where)
        self.events = events


class ManeuverGroup(Element):
    """A ``ManeuverGroup``: actors, maneuvers and ``maximumExecutionCount``.

    :ivar actors: the entities named by ``EntityRef``.
    :ivar select: ``selectTriggeringEntities``: when the act starts, the triggering
        entities of its start trigger join the actors (:attr:`cast`).
    :ivar cast: the actors the maneuvers act on: :attr:`actors`, and with
        :attr:`select` the act's triggering entities after them.
    """

    kind = "maneuverGroup"

    def __init__(
        self,
        name: str,
        where: str,
        actors: list[str],
        maneuvers: list[Maneuver],
        maximum: int,
        select: bool = False,
    ) -> None:
        """See the module docstring."""
        super().__init__(name, where)
        self.actors = actors
        self.maneuvers = maneuvers
        self.maximum = maximum
        self.select = select
        self.cast = list(actors)


class Act(Element):
    """An ``Act``: maneuver groups, a start and an optional stop trigger."""

    kind = "act"

    def __init__(
        self, name: str, where: str, groups: list[ManeuverGroup], start: Trigger, stop: Trigger
    ) -> None:
        """See the module docstring."""
        super().__init__(name, where)
        self.groups = groups
        self.start = start
        self.stop = stop


class Story(Element):
    """A ``Story``: its acts."""

    kind = "story"

    def __init__(self, name: str, where: str, acts: list[Act]) -> None:
        """See the module docstring."""
        super().__init__(name, where)
        self.acts = acts


class Storyboard:
    """The stories and the stop trigger, run by :meth:`update` once per time step.

    :param stories: the stories in document order.
    :param stop: the storyboard's stop trigger.
    """

    def __init__(self, stories: Sequence[Story], stop: Trigger) -> None:
        """See the class docstring."""
        self.stories = list(stories)
        self.stop = stop
        self.tick = 0
        self.times: list[float] = []
        """The simulation time [s] of each update (``times[tick - 1]``)."""
        self.finished = False
        self.finished_at: float | None = None
        """The simulation time [s] the stop trigger fired at."""
        self.by_name: dict[str, list[Element]] = {}
        actions = 0
        for element in self.elements():
            self.by_name.setdefault(element.name, []).append(element)
            if element.kind == "action":
                # where esmini steps it within a step: after Init's, in document order
                element.rank = (1, actions)
                actions += 1

    def elements(self) -> Iterator[Element]:
        """Every element, top down in document order."""
        for story in self.stories:
            yield story
            for act in story.acts:
                yield act
                for group in act.groups:
                    yield group
                    for maneuver in group.maneuvers:
                        yield maneuver
                        for event in maneuver.events:
                            yield event
                            yield from event.actions

    def element(self, kind: str, name: str) -> Element | None:
        """The element of that kind and name (the first in document order), or None."""
        return next((e for e in self.by_name.get(name, ()) if e.kind == kind), None)

    # ------------------------------------------------------------------ running
    def update(self, runner: Any, time: float) -> None:
        """One time step at ``time`` [s]: triggers, transitions, started actions, and
        the completion of elements whose actions ended."""
        if self.finished:
            return
        self.tick += 1
        self.times.append(float(time))
        tick = self.tick
        for story in self.stories:
            if story.state == "standbyState":
                story._move("startTransition", "runningState", tick)
            if story.state != "runningState":
                continue
            for act in story.acts:
                self._update_act(runner, act, time, tick)
            if all(a.state == "completeState" for a in story.acts):
                story._move("endTransition", "completeState", tick)
        if self.stop.fires(runner, time):
            self.finished = True
            self.finished_at = float(time)

    def starts(self, kind: str = "event") -> dict[str, list[float]]:
        """The simulation times [s] at which each element of ``kind`` started
        (``startTransition``), by name, in order."""
        out: dict[str, list[float]] = {}
        for element in self.elements():
            if element.kind != kind:
                continue
            times = out.setdefault(element.name, [])
            for transition, tick in zip(element.transitions, element.ticks, strict=True):
                if transition == "startTransition":
                    times.append(self.times[tick - 1])
        return out

    def _update_act(self, runner: Any, act: Act, time: float, tick: int) -> None:
        if act.state == "standbyState" and act.start.fires(runner, time):
            act._move("startTransition", "runningState", tick)
            for group in act.groups:
                group._move("startTransition", "runningState", tick)
                group.runs = 1
                if group.select:  # the union with the act's triggering entities
                    group.cast = list(dict.fromkeys(group.actors + act.start.fulfilled()))
        if act.state != "runningState":
            return
        if act.stop.groups and act.stop.fires(runner, time):
            self._stop(act, tick)
            return
        for group in act.groups:
            if group.state != "runningState":
                continue
            for maneuver in group.maneuvers:
                if maneuver.state == "standbyState":
                    maneuver._move("startTransition", "runningState", tick)
                if maneuver.state == "runningState":
                    self._update_maneuver(runner, group, maneuver, time, tick)
            if all(m.state == "completeState" for m in group.maneuvers):
                if group.runs < group.maximum:
                    group.runs += 1
                    for m in group.maneuvers:
                        self._reset(m, tick)
                else:
                    group._move("endTransition", "completeState", tick)
        if all(g.state == "completeState" for g in act.groups):
            act._move("endTransition", "completeState", tick)

    def _update_maneuver(
        self, runner: Any, group: ManeuverGroup, maneuver: Maneuver, time: float, tick: int
    ) -> None:
        for event in maneuver.events:
            if event.state == "runningState":
                self._finish_actions(event, tick)
        for event in maneuver.events:
            if event.state != "standbyState" or not event.start.fires(runner, time):
                continue
            running = [e for e in maneuver.events if e is not event and e.state == "runningState"]
            if event.priority == "skip" and running:
                # skipped: it stays in standby (the standard's skipTransition) and starts
                # when its trigger fires with no other event running (as esmini)
                event._move("skipTransition", "standbyState", tick)
                continue
            if event.priority == "overwrite":
                for other in running:
                    self._stop(other, tick)
            event.runs += 1
            event._move("startTransition", "runningState", tick)
            for action in event.actions:
                action._move("startTransition", "runningState", tick)
                action.instances = [action.make(runner, actor) for actor in group.cast or [None]]
                for k, instance in enumerate(action.instances):
                    instance.rank = (*action.rank, k)
                    instance.start(runner)
            # An action that ended as it started (instant) completes now, but state
            # conditions see its end from the next update on: esmini completes it in
            # the frame's action step, after the triggers were evaluated.
            self._finish_actions(event, tick, later=True)
        if all(e.state == "completeState" for e in maneuver.events):
            maneuver._move("endTransition", "completeState", tick)

    def _finish_actions(self, event: Event, tick: int, later: bool = False) -> None:
        """Complete the event's actions whose instances all ended, then the event
        (``later``: state conditions see these transitions from the next update)."""
        for action in event.actions:
            if action.state == "runningState" and all(i.done for i in action.instances):
                # an action overridden by a newer one of its domain ends by a stop
                stopped = any(getattr(i, "stopped", False) for i in action.instances)
                transition = "stopTransition" if stopped else "endTransition"
                action._move(transition, "completeState", tick, later)
        if all(a.state == "completeState" for a in event.actions):
            if event.runs < event.maximum:
                event._move("endTransition", "standbyState", tick, later)
                for a in event.actions:
                    a._set_state("standbyState", tick, later)
            else:
                event._move("endTransition", "completeState", tick, later)

    def _stop(self, element: Element, tick: int) -> None:
        """Stop a running element and everything running below it."""
        for child in _children(element):
            if child.state != "completeState":
                self._stop(child, tick)
        if isinstance(element, ActionElement):
            for instance in element.instances:
                instance.stop()
        element._move("stopTransition", "completeState", tick)

    def _reset(self, element: Element, tick: int) -> None:
        """Back to standby for a maneuver group's next execution."""
        element._set_state("standbyState", tick)
        element.runs = 0
        for child in _children(element):
            self._reset(child, tick)


def _children(element: Element) -> list[Element]:
    if isinstance(element, Story):
        return list(element.acts)
    if isinstance(element, Act):
        return list(element.groups)
    if isinstance(element, ManeuverGroup):
        return list(element.maneuvers)
    if isinstance(element, Maneuver):
        return list(element.events)
    if isinstance(element, Event):
        return list(element.actions)
    return []
