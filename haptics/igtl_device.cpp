#include "haptics/igtl_device.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlSensorMessage.h>
#include <igtlServerSocket.h>
#include <igtlTimeStamp.h>
#include <igtlTransformMessage.h>
#include <igtlUnit.h>
#include <igtl_transform.h>

#include "engine/util/error.h"

namespace incise {
namespace {

constexpr int kPollMs = 100;      // how soon the network thread notices stop(), and the send limit
constexpr int kStallPolls = 10;   // a message stuck halfway this many polls (1 s) drops the client
constexpr int kMaxSkippedBody = 16 << 20;  // bytes of another message type skipped at most (an image is larger: drop)

// The descriptor of an igtl socket, which the library keeps protected: a
// pointer to member formed through a derived class may name it.
struct SocketFd : igtl::Socket {
  static int& of(igtl::Socket& s) { return s.*(&SocketFd::m_SocketDescriptor); }
};

// libOpenIGTLink 1.11's CloseSocket() only shutdown()s: the descriptor leaks
// and a listening port stays bound until the process exits. Close it here
// and mark it closed, so that the library's destructor leaves it alone.
void close_socket(igtl::Socket& s) {
  int& fd = SocketFd::of(s);
  if (fd < 0) return;
  ::shutdown(fd, SHUT_RDWR);
  ::close(fd);
  fd = -1;
}

bool is_rotation(const Eigen::Matrix3d& r) {
  if (!r.allFinite()) return false;
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3) return false;
  return r.determinant() > 0.0;
}

// The matrix is row-major, x_tracker = R x_tool + p (OpenIGTLink's
// convention). Not a rotation: NaN quaternion, for the loop's input guard.
ToolPose pose_from_matrix(const igtl::Matrix4x4& m) {
  ToolPose pose;
  Eigen::Matrix3d r;
  for (int i = 0; i < 3; ++i) {
    pose.p[i] = m[i][3];
    for (int j = 0; j < 3; ++j) r(i, j) = m[i][j];
  }
  pose.jaw = 0.0;
  if (!is_rotation(r)) {
    pose.q.fill(std::numeric_limits<double>::quiet_NaN());
    return pose;
  }
  Eigen::Quaterniond q(r);  // the float matrix is orthonormal to ~1e-7 only
  q.normalize();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // one of the two, so readings compare
  pose.q = {q.w(), q.x(), q.y(), q.z()};
  return pose;
}

std::string show(double x) {
  std::ostringstream out;
  out << x;
  return out.str();
}

}  // namespace

// igtl::ServerSocket::CreateServer() in 1.11 binds without SO_REUSEADDR (a
// restart fails for a minute after the device closed a connection: TIME_WAIT),
// reports no errno and leaks the descriptor when it fails. Same socket, those
// fixed; WaitForConnection() and GetServerPort() are the library's.
class IgtlDevice::Listener : public igtl::ServerSocket {
 public:
  typedef igtl::SmartPointer<Listener> Pointer;
  static Pointer New() {
    Pointer p = new Listener;
    p->UnRegister();  // as igtlNewMacro: the smart pointer holds the only reference
    return p;
  }
  // 0, or the errno of the call that failed.
  int listen_on(int port) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) return errno;
    m_SocketDescriptor = fd;
    const int on = 1;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_ANY);
    addr.sin_port = htons(static_cast<uint16_t>(port));
    if (::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on) != 0 ||
        ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 1) != 0) {
      const int err = errno;
      close_socket(*this);
      return err;
    }
    return 0;
  }

 protected:
  Listener() = default;
  ~Listener() { close_socket(*this); }
};

// The network thread's messages, allocated once.
struct IgtlDevice::Messages {
  igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
  igtl::TransformMessage::Pointer transform = igtl::TransformMessage::New();
  igtl::SensorMessage::Pointer force = igtl::SensorMessage::New();
  igtl::TimeStamp::Pointer stamp = igtl::TimeStamp::New();

  Messages() {
    force->SetDeviceName("FORCE");
    force->SetLength(3);
    // NEWTON, not kg m s^-2: 1.11's Unit::Append() never advances past the
    // first unit, so only a one-unit product survives packing.
    igtl::Unit::Pointer unit = igtl::Unit::New();
    unit->Append(igtl::Unit::SI_DERIVED_NEWTON, 1);
    force->SetUnit(unit);
  }
};

IgtlDevice::IgtlDevice(int port, double max_force)
    : requested_port_(port), max_force_(max_force), port_(port) {
  if (port < 0 || port > 65535)
    throw Error("openigtlink: port must be a TCP port in [0, 65535] (0: any free one), got " + std::to_string(port));
  if (!(std::isfinite(max_force) && max_force > 0.0))
    throw Error("openigtlink: max_force must be finite and > 0 N, got " + show(max_force));
}

IgtlDevice::~IgtlDevice() { stop(); }

std::string IgtlDevice::describe() const { return "openigtlink (TCP port " + std::to_string(port()) + ")"; }

void IgtlDevice::start() {
  if (thread_.joinable()) throw Error("openigtlink: start() while the device runs (call stop() first)");
  Listener::Pointer listener = Listener::New();
  if (const int err = listener->listen_on(requested_port_)) {
    const char* hint = err == EADDRINUSE ? " (another program holds it; port 0 takes any free one)"
                       : err == EACCES   ? " (ports below 1024 need privileges)"
                                         : "";
    throw Error("openigtlink: cannot listen on TCP port " + std::to_string(requested_port_) + ": " +
                std::strerror(err) + hint);
  }
  port_ = listener->GetServerPort();
  running_ = true;
  // The listener (a smart pointer) lives with the thread: only it touches sockets.
  thread_ = std::thread([this, listener] { serve(*listener); });
}

void IgtlDevice::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

bool IgtlDevice::read(double, DeviceSample& out) {
  const bool fresh = poses_.update();
  if (!fresh && !have_pose_) return false;
  have_pose_ = true;
  out.pose = poses_.read_buffer();
  out.buttons = 0;
  out.fresh = fresh;
  return true;
}

void IgtlDevice::write_force(double, const std::array<double, 3>& force) {
  forces_.write_buffer() = force;
  forces_.publish();
}

void IgtlDevice::adopt(igtl::ClientSocket& client) {
  // Timeouts so that stop() is noticed within kPollMs, reading or sending.
  client.SetReceiveTimeout(kPollMs);
  client.SetSendTimeout(kPollMs);
  // 1.11 does not set it on accepted sockets; a reply must not wait for an ACK.
  const int on = 1;
  ::setsockopt(SocketFd::of(client), IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  connections_.fetch_add(1);
  connected_ = true;
}

void IgtlDevice::serve(Listener& listener) {
  Messages m;
  igtl::ClientSocket::Pointer client;
  auto drop = [&] {
    close_socket(*client);
    client = nullptr;
    connected_ = false;
  };
  while (running_.load()) {
    if (!client) {
      client = listener.WaitForConnection(kPollMs);  // null on timeout
      if (client) adopt(*client);
      continue;
    }
    const Io io = serve_message(*client, m);
    if (io == Io::dropped) {
      drop();
    } else if (io == Io::idle) {
      // Silent for kPollMs: a waiting newcomer replaces it (1 ms: 0 would block).
      igtl::ClientSocket::Pointer next = listener.WaitForConnection(1);
      if (next) {
        drop();
        client = next;
        adopt(*client);
      }
    }
  }
  if (client) drop();
  close_socket(listener);
}

IgtlDevice::Io IgtlDevice::serve_message(igtl::Socket& client, Messages& m) {
  m.header->InitPack();
  Io io = receive(client, m.header->GetPackPointer(), m.header->GetPackSize(), /*idle_ok=*/true);
  if (io != Io::done) return io;
  // Another header version (protocol 3's extended header): 1.11 cannot read
  // it, so the body size is unknown and the stream lost.
  if (!(m.header->Unpack() & igtl::MessageHeader::UNPACK_HEADER)) {
    rejected_.fetch_add(1);
    return Io::dropped;
  }
  const int body = m.header->GetBodySizeToRead();  // 1.11 truncates the 64-bit size to int
  if (body < 0) {
    rejected_.fetch_add(1);
    return Io::dropped;
  }
  if (body > kMaxSkippedBody) {  // a tracker sends transforms, not volumes: a client announcing this much is lost
    rejected_.fetch_add(1);
    return Io::dropped;
  }
  if (std::strcmp(m.header->GetDeviceType(), "TRANSFORM") != 0) return skip(client, body);
  if (body != IGTL_TRANSFORM_SIZE) {  // 1.11's TransformMessage reads 48 bytes whatever the size
    rejected_.fetch_add(1);
    return skip(client, body);
  }
  m.transform->SetMessageHeader(m.header);
  m.transform->AllocatePack();
  io = receive(client, m.transform->GetPackBodyPointer(), body, /*idle_ok=*/false);
  if (io != Io::done) return io;
  if (!(m.transform->Unpack(/*crccheck=*/1) & igtl::MessageHeader::UNPACK_BODY)) {
    rejected_.fetch_add(1);  // bad CRC: the body is read whole, the stream stays in step
    return Io::done;
  }
  igtl::Matrix4x4 matrix;
  m.transform->GetMatrix(matrix);
  poses_.write_buffer() = pose_from_matrix(matrix);
  poses_.publish();
  transforms_.fetch_add(1);
  return send_force(client, m) ? Io::done : Io::dropped;
}

IgtlDevice::Io IgtlDevice::receive(igtl::Socket& client, void* data, int size, bool idle_ok) {
  // Receive(..., readFully=1) would lose a partial read at a timeout: one
  // recv() at a time, the loop here.
  char* bytes = static_cast<char*>(data);
  int got = 0, stalls = 0;
  while (got < size) {
    if (!running_.load()) return Io::dropped;  // a client that keeps dribbling bytes must not hold stop() up
    errno = 0;
    const int n = client.Receive(bytes + got, size - got, /*readFully=*/0);
    if (n > 0) {
      got += n;
      stalls = 0;
      continue;
    }
    // 0: the client closed; -1 without EAGAIN: a socket error (reset).
    if (n == 0 || !(errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return Io::dropped;
    if (!running_.load()) return Io::dropped;
    if (got == 0 && idle_ok) return Io::idle;
    if (++stalls >= kStallPolls) {
      rejected_.fetch_add(1);
      return Io::dropped;
    }
  }
  return Io::done;
}

IgtlDevice::Io IgtlDevice::skip(igtl::Socket& client, int size) {
  char sink[4096];
  while (size > 0) {
    const int n = std::min(size, static_cast<int>(sizeof sink));
    if (const Io io = receive(client, sink, n, /*idle_ok=*/false); io != Io::done) return io;
    size -= n;
  }
  return Io::done;
}

bool IgtlDevice::send_force(igtl::Socket& client, Messages& m) {
  forces_.update();
  const std::array<double, 3>& f = forces_.read_buffer();
  for (unsigned i = 0; i < 3; ++i) m.force->SetValue(i, f[i]);
  m.stamp->GetTime();
  m.force->SetTimeStamp(m.stamp);
  m.force->Pack();
  if (!client.Send(m.force->GetPackPointer(), m.force->GetPackSize())) return false;  // gone, or not reading
  forces_sent_.fetch_add(1);
  return true;
}

}  // namespace incise
