"""Wire formats derived from their definitions: CDR primitives (``cdr``), message layouts parsed from
the `.msg` files (``definitions``, ``layout``), messages written by those layouts (``compose``,
``template``) and the package's messages: outputs, markers, diagnostics, input readings. Below
``bag`` and ``ros``; no rclpy."""
