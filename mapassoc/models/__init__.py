"""Models of targets and sensors: motion, measurement, sensors and clutter, initiation
(birth) and the target population (undetected targets).
"""
