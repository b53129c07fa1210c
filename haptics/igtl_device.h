#pragma once
// A tracker or navigation system drives the tool over OpenIGTLink (protocol
// 2, libOpenIGTLink 1.11): incise listens on a TCP port (scene.json
// haptics.port, 18944 by default, the OpenIGTLink port) and serves one client
// at a time.
//
// In: TRANSFORM messages, any device name: the 4x4 matrix tool -> tracker,
// translation in the sender's units (Slicer and PLUS send millimetres; the
// haptic loop maps them with haptics.scale, 0.001 by default for this device)
// and a rotation, which must be one: a scaled, sheared, mirrored or
// non-finite 3x3 gives a NaN quaternion that the loop's input guard rejects
// and logs. The newest transform wins; a bad CRC or a malformed TRANSFORM is
// counted in rejected_messages() and skipped; every other message type is
// skipped. Headers must be version 1 (protocols 1 and 2, all that 1.11
// reads): a client sending protocol 3's version 2 headers is dropped.
// Out: after each TRANSFORM, one SENSOR message named "FORCE": 3 float64, the
// latest force from write_force() in newtons (world axes, unit NEWTON), so a
// client in lock step gets one reply per transform. A client that does not
// want them must still read them off the socket: one the device cannot send
// to for 100 ms is dropped.
//
// 3D Slicer: OpenIGTLinkIF module, add a connector of type client to this
// host and port, activate it, and add the tool's linear transform node to its
// outgoing nodes; Slicer sends a TRANSFORM each time the node changes. A PLUS
// server (PlusServer) is itself an OpenIGTLink server and only serves, so
// relay it: one Slicer connector as client to PlusServer (its StylusToTracker
// transform arrives as a node), a second as client to incise with that node
// outgoing. Any client library works the same way (libOpenIGTLink, pyigtl).
//
// A client that stays silent for 100 ms while another one is waiting is
// dropped for the newcomer (a tracker PC that rebooted never closes its old
// connection). The port listens on every interface without authentication:
// use it on the OR network or a loopback, not the internet.
#include <array>
#include <atomic>
#include <string>
#include <thread>

#include "haptics/device.h"
#include "haptics/triple_buffer.h"

namespace igtl {
class Socket;
class ClientSocket;
}  // namespace igtl

namespace incise {

class IgtlDevice : public HapticDevice {
 public:
  // port: the TCP port to listen on, in [0, 65535]; 0 takes any free one
  // (port() says which after start()). max_force: N, finite and > 0.
  IgtlDevice(int port, double max_force);
  ~IgtlDevice() override;
  IgtlDevice(const IgtlDevice&) = delete;
  IgtlDevice& operator=(const IgtlDevice&) = delete;

  std::string describe() const override;  // "openigtlink (TCP port 18944)"
  double max_force() const override { return max_force_; }
  // Listens and starts the network thread; throws incise::Error when the
  // port cannot be had, or when the device runs already.
  void start() override;
  // Closes the connection and the port and joins the network thread (within
  // about 100 ms); idempotent, and the destructor calls it.
  void stop() override;
  // Haptic thread only (one reader, one writer): no allocation, no lock.
  bool read(double t, DeviceSample& out) override;
  void write_force(double t, const std::array<double, 3>& force) override;

  // For tests and logs; any thread.
  int port() const { return port_.load(); }  // the bound one after start()
  long transforms_received() const { return transforms_.load(); }
  long forces_sent() const { return forces_sent_.load(); }
  int connections() const { return connections_.load(); }  // clients accepted so far
  long rejected_messages() const { return rejected_.load(); }
  bool connected() const { return connected_.load(); }

 private:
  struct Messages;
  enum class Io { done, idle, dropped };
  class Listener;

  void serve(Listener& listener);
  Io serve_message(igtl::Socket& client, Messages& m);
  Io receive(igtl::Socket& client, void* data, int size, bool idle_ok);
  Io skip(igtl::Socket& client, int size);
  bool send_force(igtl::Socket& client, Messages& m);
  void adopt(igtl::ClientSocket& client);

  const int requested_port_;
  const double max_force_;
  std::atomic<int> port_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  TripleBuffer<ToolPose> poses_;                 // network thread -> haptic thread
  TripleBuffer<std::array<double, 3>> forces_;   // haptic thread -> network thread
  bool have_pose_ = false;                       // the haptic thread's: a transform arrived once
  std::atomic<long> transforms_{0}, forces_sent_{0}, rejected_{0};
  std::atomic<int> connections_{0};
  std::atomic<bool> connected_{false};
};

}  // namespace incise
