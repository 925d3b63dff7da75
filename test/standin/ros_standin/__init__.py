"""Machinery behind the test-only rclpy stand-in (messages, test clock, graph, log records).

Node code never imports this package; tests reach it through the fixtures in test/conftest.py.
"""
