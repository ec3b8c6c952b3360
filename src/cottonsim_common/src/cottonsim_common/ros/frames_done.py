"""/sim/frames_done: a camera frame's consumer says it is done with it (the simulator's pacing input).

A node that takes frames of a camera rendered at its rate publishes, for each
frame it took (processed, black, skipped), a std_msgs/Header with the frame's
stamp and the camera's name as frame_id. The simulator's bridge, set to wait for
a camera's consumer (``CameraConfig.consumer_wait_s``), does not step past the
end of a frame's slot before that message came (cottonsim_world.consumer_wait).
Without a simulator waiting for it the message costs one small publish per frame.
"""
import rospy
from std_msgs.msg import Header

FRAMES_DONE_TOPIC = "/sim/frames_done"


class FramesDonePublisher:
    """Publishes 'done with the frame of ``camera`` stamped ``stamp``' on /sim/frames_done."""

    def __init__(self):
        self.publisher = rospy.Publisher(FRAMES_DONE_TOPIC, Header, queue_size=20)

    def done(self, camera: str, stamp: rospy.Time) -> None:
        self.publisher.publish(Header(stamp=stamp, frame_id=camera))
