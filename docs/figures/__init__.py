"""Draw the thesis's pictures from the project's own ``dynamics``, with the numbers behind them.

Run from the repository root (``--quick`` draws coarser pictures, a few times faster)::

    python -m docs.figures [--out docs/img] [--quick]

It writes ``thesis_*.png`` (chapter 3 and appendix A of the thesis in ``docs/physics.md``),
one module per picture:

* ``torus_portrait``: ``thesis_torus_portrait.png``, the flow on the energy torus
  (alpha_1, beta), n = 1, a > 0;
* ``straight_line``: ``thesis_straight_line.png``, the cart's path straightening out, a > 0;
* ``level_function``: ``thesis_level_function.png``, f(alpha) = sin^2(alpha)/R(alpha) and
  energy levels, n = 1, a = 0;
* ``invariant_circles``: ``thesis_invariant_circles.png``, the invariant circles and the
  cylinder omega = omega_0;
* ``cart_paths``: ``thesis_cart_paths.png``, quasi-periodic, periodic and limiting-circle
  paths of the cart;
* ``singular_set``: ``thesis_singular_set.png``, the degree of nonholonomy over the
  hitch-angle torus, n = 2, 3.

Every picture has a pure function computing its numbers (``*_data`` and a few helpers),
which ``tests/docs/test_figures.py`` checks, and a function drawing them (``draw_*``);
``_common`` holds what several pictures share and ``command`` the command. All physics
comes from ``dynamics``: this package only samples, integrates, interpolates and fits.
"""
