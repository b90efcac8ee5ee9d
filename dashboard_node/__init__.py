"""The dashboard: watch and steer a running swarm in the browser (``aes-dashboard``).

:mod:`dashboard_node.node` is the ROS node, :mod:`dashboard_node.server` its web
server, :mod:`dashboard_node.view` what the page shows, :mod:`dashboard_node.controls`
what a viewer may ask; the page itself is in ``static/``.
"""
