"""Thin rclpy node classes around the ROS-free core."""
