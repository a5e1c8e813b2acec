// The Fast DDS ping-pong of `tutti bench gateway`, built by the benchmark against Debian's
// libfastrtps (Fast DDS 2.x): g++ -std=c++11 -O2 fastdds_pingpong.cpp -lfastrtps -lfastcdr.
//
// One sample is an octet array as large as the gateway's benchmark sample (uint64 step,
// double sim_time, 8 x double: 80 bytes), with a hand-written type support (plain CDR,
// little endian). UDPv4 on 127.0.0.1 only: the built-in transports (shared memory among
// them) are off, data sharing is off, discovery goes to 127.0.0.1. RELIABLE, KEEP_LAST 1.
//
// Usage: fastdds_pingpong DOMAIN_ID ping N   N timed round trips after a warm-up; prints
//                                            "rtt_us p50=P p99=Q n=N lost=L"
//        fastdds_pingpong DOMAIN_ID pong     answers every ping until SIGINT or SIGTERM
// Exit status: 0 done, 2 usage, 1 DDS failure, 3 no pong within 30 s.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>

using namespace eprosima::fastdds::dds;
using eprosima::fastdds::rtps::UDPv4TransportDescriptor;
using eprosima::fastrtps::rtps::InstanceHandle_t;
using eprosima::fastrtps::rtps::SerializedPayload_t;

namespace {

const uint32_t kSize = 16 + 64;  // step, sim_time, 8 x float64
const uint32_t kHeader = 4;      // CDR encapsulation

struct Sample {
    unsigned char bytes[kSize];
};

// The type support of Sample: 4 bytes of encapsulation (CDR_LE), then the octets.
class SampleType : public TopicDataType {
public:
    SampleType() {
        setName("tutti_bench::msg::dds_::PingPong_");
        m_typeSize = kHeader + kSize;
        m_isGetKeyDefined = false;
        auto_fill_type_object(false);
        auto_fill_type_information(false);
    }
    bool serialize(void* data, SerializedPayload_t* payload) override {
        if (payload->max_size < kHeader + kSize) return false;
        const unsigned char header[kHeader] = {0x00, 0x01, 0x00, 0x00};
        std::memcpy(payload->data, header, kHeader);
        std::memcpy(payload->data + kHeader, static_cast<Sample*>(data)->bytes, kSize);
        payload->length = kHeader + kSize;
        payload->encapsulation = CDR_LE;
        return true;
    }
    bool deserialize(SerializedPayload_t* payload, void* data) override {
        if (payload->length < kHeader + kSize) return false;
        std::memcpy(static_cast<Sample*>(data)->bytes, payload->data + kHeader, kSize);
        return true;
    }
    std::function<uint32_t()> getSerializedSizeProvider(void*) override {
        return [] { return kHeader + kSize; };
    }
    void* createData() override { return new Sample(); }
    void deleteData(void* data) override { delete static_cast<Sample*>(data); }
    bool getKey(void*, InstanceHandle_t*, bool) override { return false; }
};

std::atomic<bool> stop_requested(false);

void on_signal(int) { stop_requested.store(true); }

uint64_t step_of(const Sample& s) {
    uint64_t v;
    std::memcpy(&v, s.bytes, sizeof v);
    return v;
}

// One participant with a writer on `out` and a reader on `in`.
struct Side {
    DomainParticipant* dp = nullptr;
    DataWriter* writer = nullptr;
    DataReader* reader = nullptr;

    bool open(int domain, const char* out, const char* in) {
        DomainParticipantQos pq;
        pq.transport().use_builtin_transports = false;
        auto udp = std::make_shared<UDPv4TransportDescriptor>();
        udp->interfaceWhiteList.push_back("127.0.0.1");
        pq.transport().user_transports.push_back(udp);
        eprosima::fastrtps::rtps::Locator_t peer;
        eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
        pq.wire_protocol().builtin.initialPeersList.push_back(peer);
        pq.name("tutti_bench_fastdds");
        dp = DomainParticipantFactory::get_instance()->create_participant(domain, pq);
        if (!dp) return false;
        TypeSupport type(new SampleType());
        type.register_type(dp);
        Topic* tout = dp->create_topic(out, type.get_type_name(), TOPIC_QOS_DEFAULT);
        Topic* tin = dp->create_topic(in, type.get_type_name(), TOPIC_QOS_DEFAULT);
        Publisher* pub = dp->create_publisher(PUBLISHER_QOS_DEFAULT);
        Subscriber* sub = dp->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
        if (!tout || !tin || !pub || !sub) return false;
        DataWriterQos wq = DATAWRITER_QOS_DEFAULT;
        wq.reliability().kind = RELIABLE_RELIABILITY_QOS;
        wq.history().kind = KEEP_LAST_HISTORY_QOS;
        wq.history().depth = 1;
        wq.data_sharing().off();
        DataReaderQos rq = DATAREADER_QOS_DEFAULT;
        rq.reliability().kind = RELIABLE_RELIABILITY_QOS;
        rq.history().kind = KEEP_LAST_HISTORY_QOS;
        rq.history().depth = 1;
        rq.data_sharing().off();
        writer = pub->create_datawriter(tout, wq);
        reader = sub->create_datareader(tin, rq);
        return writer && reader;
    }

    ~Side() {
        if (dp) {
            dp->delete_contained_entities();
            DomainParticipantFactory::get_instance()->delete_participant(dp);
        }
    }

    // Waits up to `limit` for a sample; true with it in `s`.
    bool take(Sample& s, std::chrono::microseconds limit) {
        SampleInfo info;
        auto end = std::chrono::steady_clock::now() + limit;
        for (;;) {
            while (reader->take_next_sample(&s, &info) == ReturnCode_t::RETCODE_OK) {
                if (info.valid_data) return true;
            }
            auto now = std::chrono::steady_clock::now();
            if (now >= end) return false;
            auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(end - now).count();
            eprosima::fastrtps::Duration_t d(static_cast<int32_t>(left / 1000000000),
                                             static_cast<uint32_t>(left % 1000000000));
            reader->wait_for_unread_message(d);
        }
    }
};

int pong(int domain) {
    Side side;
    if (!side.open(domain, "fastdds_pong", "fastdds_ping")) return 1;
    Sample s;
    while (!stop_requested.load()) {
        if (side.take(s, std::chrono::milliseconds(100))) side.writer->write(&s);
    }
    return 0;
}

int ping(int domain, int n) {
    Side side;
    if (!side.open(domain, "fastdds_ping", "fastdds_pong")) return 1;
    Sample s;
    std::memset(s.bytes, 0, kSize);
    uint64_t step = 0;
    // One round trip of step `k`; true when the answer came within `limit`.
    auto once = [&](std::chrono::microseconds limit) {
        ++step;
        std::memcpy(s.bytes, &step, sizeof step);
        side.writer->write(&s);
        Sample back;
        auto end = std::chrono::steady_clock::now() + limit;
        for (;;) {
            auto now = std::chrono::steady_clock::now();
            if (now >= end) return false;
            auto left = std::chrono::duration_cast<std::chrono::microseconds>(end - now);
            if (side.take(back, left) && step_of(back) == step) return true;
        }
    };
    // Until the path works both ways (the pong may not have matched our reader yet).
    auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (!once(std::chrono::milliseconds(100))) {
        if (std::chrono::steady_clock::now() > give_up || stop_requested.load()) {
            std::fprintf(stderr, "fastdds_pingpong: no pong within 30 s\n");
            return 3;
        }
    }
    for (int i = 0; i < std::min(n, 1000); i++) once(std::chrono::seconds(1));
    std::vector<double> us;
    us.reserve(n);
    int lost = 0;
    for (int i = 0; i < n && !stop_requested.load(); i++) {
        auto t = std::chrono::steady_clock::now();
        if (once(std::chrono::seconds(1))) {
            us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t).count());
        } else if (++lost >= 20) {
            break;  // the pong is gone
        }
    }
    if (us.empty()) return 3;
    std::sort(us.begin(), us.end());
    auto rank = [&](double q) {
        size_t r = static_cast<size_t>(std::ceil(us.size() * q));
        return us[std::min(std::max<size_t>(r, 1), us.size()) - 1];
    };
    std::printf("rtt_us p50=%.1f p99=%.1f n=%zu lost=%d\n", rank(0.5), rank(0.99), us.size(), lost);
    std::fflush(stdout);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    if (argc >= 4 && std::strcmp(argv[2], "ping") == 0) return ping(std::atoi(argv[1]), std::atoi(argv[3]));
    if (argc >= 3 && std::strcmp(argv[2], "pong") == 0) return pong(std::atoi(argv[1]));
    std::fprintf(stderr, "usage: %s DOMAIN_ID ping N | DOMAIN_ID pong\n", argv[0]);
    return 2;
}
