"""Tracking methods behind one interface (:class:`~mapassoc.trackers.base.Tracker`)."""
