"""The guidance (outer) loop: altitude, course and speed targets -> the attitude commands of
the paper's law (fc.control) and a throttle command. Pure, like fc.control: no sockets,
clocks, logging or MAVLink. See docs/guidance.md."""
