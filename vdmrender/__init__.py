"""vdmrender: renders a bundle with each requested technique and an independent reference,
and reports CIE-Luv error against run time."""

from vdmbake import __version__  # noqa: F401  (one version for both tools)
