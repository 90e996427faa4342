"""Drop-ins with the peers' call forms and returns: :mod:`optdesign.compat.scipy` (scipy's
``place_poles``) and :mod:`optdesign.compat.control` (python-control's ``place``, ``lqe``, ``dlqe``,
``lqr``, ``dlqr``, ``create_estimator_iosystem``).  Each is a thin layer over the native verbs;
the native verbs keep their result objects.
"""
