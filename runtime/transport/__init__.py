"""The transport seam (``base``), its two backends (``ros2``, ``zenoh``) and the factory that
picks one (``factory``)."""
