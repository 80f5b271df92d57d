"""Bridges to other tracking libraries, each an optional extra.

* :mod:`mapassoc.interop.stonesoup`: Stone Soup detections, tracks, ground truth and metric
  managers (``pip install 'mapassoc[stonesoup]'``).

Importing a bridge module never imports the other library; its functions do, and raise an
:class:`ImportError` naming the extra to install when it is missing.
"""
