// ns-3 (3.37, Debian package libns3-dev) reference for `cosim radio`: PDR vs distance of 802.11p broadcasts
// (OCB, 10 MHz, 6 Mb/s) over the 3GPP TR 37.885 highway LOS path loss with 3 dB log-normal shadowing.
// One sender at x = 0 broadcasts `packets` UDP packets at 10 Hz to receivers every metre from 1 m to
// `maxDist` m on a line (antennas 1.5 m high); each link has its own shadowing (ns-3's 3GPP model) and the
// receivers only listen, so the PDR comes from the link budget and the receiver alone.
// Receiver set like cosim's defaults: noise figure 9 dB (-95 dBm over 10 MHz), sensitivity -89 dBm,
// preamble detection from -89 dBm at >= 4 dB SNR; tx power 13 dBm.
// Output: one line per receiver, "distance_m received sent".
// Build and run: see validation/ns3/README.md.
#include "ns3/core-module.h"
#include "ns3/internet-module.h"
#include "ns3/mobility-module.h"
#include "ns3/network-module.h"
#include "ns3/propagation-module.h"
#include "ns3/wave-module.h"
#include "ns3/wifi-module.h"

#include <iostream>
#include <vector>

using namespace ns3;

static std::vector<uint32_t> g_rx;

static void
Receive(Ptr<Socket> socket)
{
    while (socket->Recv())
    {
        g_rx[socket->GetNode()->GetId()]++;
    }
}

int
main(int argc, char* argv[])
{
    uint32_t packets = 50;
    uint32_t maxDist = 1000;
    uint32_t size = 200;
    uint32_t run = 1;
    CommandLine cmd;
    cmd.AddValue("packets", "packets sent", packets);
    cmd.AddValue("maxDist", "farthest receiver [m]", maxDist);
    cmd.AddValue("size", "UDP payload [B]", size);
    cmd.AddValue("run", "RngRun", run);
    cmd.Parse(argc, argv);
    RngSeedManager::SetSeed(1);
    RngSeedManager::SetRun(run);

    NodeContainer nodes;
    nodes.Create(maxDist + 1);
    g_rx.assign(maxDist + 1, 0);
    MobilityHelper mob;
    Ptr<ListPositionAllocator> pos = CreateObject<ListPositionAllocator>();
    for (uint32_t i = 0; i <= maxDist; ++i)
    {
        pos->Add(Vector(double(i), 0.0, 1.5));
    }
    mob.SetPositionAllocator(pos);
    mob.SetMobilityModel("ns3::ConstantPositionMobilityModel");
    mob.Install(nodes);

    Ptr<YansWifiChannel> channel = CreateObject<YansWifiChannel>();
    Ptr<ThreeGppV2vHighwayPropagationLossModel> loss = CreateObject<ThreeGppV2vHighwayPropagationLossModel>();
    loss->SetAttribute("Frequency", DoubleValue(5.89e9));
    loss->SetAttribute("ShadowingEnabled", BooleanValue(true));
    loss->SetChannelConditionModel(CreateObject<AlwaysLosChannelConditionModel>());
    channel->SetPropagationLossModel(loss);
    channel->SetPropagationDelayModel(CreateObject<ConstantSpeedPropagationDelayModel>());

    YansWifiPhyHelper phy;
    phy.SetChannel(channel);
    phy.Set("TxPowerStart", DoubleValue(13.0));
    phy.Set("TxPowerEnd", DoubleValue(13.0));
    phy.Set("RxNoiseFigure", DoubleValue(9.0));
    phy.Set("RxSensitivity", DoubleValue(-89.0));
    phy.SetPreambleDetectionModel("ns3::ThresholdPreambleDetectionModel",
                                  "MinimumRssi", DoubleValue(-89.0), "Threshold", DoubleValue(4.0));
    NqosWaveMacHelper mac = NqosWaveMacHelper::Default();
    Wifi80211pHelper wifi = Wifi80211pHelper::Default();
    wifi.SetRemoteStationManager("ns3::ConstantRateWifiManager", "DataMode", StringValue("OfdmRate6MbpsBW10MHz"),
                                 "ControlMode", StringValue("OfdmRate6MbpsBW10MHz"));
    NetDeviceContainer devs = wifi.Install(phy, mac, nodes);

    InternetStackHelper inet;
    inet.Install(nodes);
    Ipv4AddressHelper ip;
    ip.SetBase("10.1.0.0", "255.255.0.0");
    ip.Assign(devs);
    TypeId tid = TypeId::LookupByName("ns3::UdpSocketFactory");
    for (uint32_t i = 1; i <= maxDist; ++i)
    {
        Ptr<Socket> s = Socket::CreateSocket(nodes.Get(i), tid);
        s->Bind(InetSocketAddress(Ipv4Address::GetAny(), 80));
        s->SetRecvCallback(MakeCallback(&Receive));
    }
    Ptr<Socket> src = Socket::CreateSocket(nodes.Get(0), tid);
    src->SetAllowBroadcast(true);
    src->Connect(InetSocketAddress(Ipv4Address("255.255.255.255"), 80));
    for (uint32_t k = 0; k < packets; ++k)
    {
        Simulator::Schedule(Seconds(1.0 + 0.1 * k), [src, size]() { src->Send(Create<Packet>(size)); });
    }
    Simulator::Stop(Seconds(2.0 + 0.1 * packets));
    Simulator::Run();
    for (uint32_t i = 1; i <= maxDist; ++i)
    {
        std::cout << i << " " << g_rx[i] << " " << packets << "\n";
    }
    Simulator::Destroy();
    return 0;
}
