"""Wire formats derived from their definitions: CDR primitives (``cdr``), message layouts parsed from
the `.msg` files (``definitions``, ``layout``), messages written by those layouts (``compose``,
``template``) and the package's messages: the input events read from their bytes, the outputs,
markers and diagnostics, and what one monitoring step sends (``step_messages``). Below ``bag`` and
``ros``; no rclpy."""
